// probekit::viewer — a glTF scene and its volumes on the runtime renderer.
//
// probekit::baker loads scenes and probekit::runtime draws triangles; the two never include each
// other (ARCHITECTURE.md#layers). This layer joins them for an application that shows a baked
// scene: the scene flattened to render triangles with its textures, the lights the renderer
// adds, the camera's framing box, the environment behind the geometry, and a placeholder volume
// for a scene shown without a .pvol. `probekit render` is one such application. Nothing here
// prints: warnings are returned for the caller to show.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "probekit/baker/scene.hpp"
#include "probekit/formats/environment.hpp"
#include "probekit/formats/grid.hpp"
#include "probekit/formats/light.hpp"
#include "probekit/formats/pvol.hpp"
#include "probekit/formats/result.hpp"
#include "probekit/formats/volume.hpp"
#include "probekit/runtime/renderer.hpp"

namespace probekit::viewer {

// The renderer's triangles: three vertices each, with the glTF vertex normals (the face normal
// for all three where any is missing), the base-colour factor and uv where the material has a
// base-colour texture (sampled per pixel from `textures`, the referenced scene images) and the
// albedo otherwise, and per-vertex emission. Degenerate triangles have no normal and are
// skipped. Beyond the renderer's texture limit (runtime::kMaxRenderTextures), materials fall
// back to albedo sampled per vertex, with a warning.
struct RenderScene {
    std::vector<runtime::RenderVertex> vertices;
    std::vector<uint32_t> indices;
    std::vector<int32_t> triangleTextures; // per triangle: index into textures, or -1
    std::vector<RgbaImage> textures;
    std::vector<std::string> warnings;
};

RenderScene flattenScene(const baker::Scene& scene);

// Gives the renderer the scene's textures and triangles.
Result<void> uploadScene(runtime::Renderer& renderer, const RenderScene& scene);

// What a default camera frames: the scene's bounds, or the volumes' when it has no triangles.
grid::Aabb framedBox(const baker::Scene& scene, const std::vector<Volume>& volumes);

// The scene's punctual lights the renderer adds as direct light: those whose direct light the
// volumes left out, by the light modes their bake recorded (docs/baking.md#light-modes: modes
// indirect and none; every light when the file records no modes, as files before them), the
// first runtime::kMaxRenderLights of them. `baked` counts the lights left to the volumes,
// `dropped` those past the limit. A recorded per_light key the scene has no light for is an
// error naming `source`.
struct LightSelection {
    std::vector<PunctualLight> lights;
    size_t baked = 0;
    size_t dropped = 0;
};

Result<LightSelection> directLights(const baker::Scene& scene, const BakeMetadata& metadata,
                                    const std::string& source);

// Per pixel of a frame rendered with its G-buffer read back (FrameSettings::readbackGBuffer),
// which of `lights` reach the pixel's surface point (runtime::FrameSettings::lightVisibility),
// traced against the scene (baker::lightVisibility).
Result<std::vector<uint32_t>> lightVisibility(const baker::Scene& scene,
                                              const runtime::Frame& gbuffer,
                                              std::span<const PunctualLight> lights);

// The environment `spec` names, as `probekit bake --env` reads it: "none" (black), "R,G,B"
// constant radiance in W/sr/m^2, or a lat-long image file. Errors name `source`.
Result<Environment> environmentFromSpec(const std::string& spec, const std::string& source);

// The environment the volumes were baked with, as the .pvol's recorded bake settings hold it:
// black when they record none. A record that does not parse is an error naming `source`. The
// .pvol is untrusted, so a recorded file is opened only when it resolves under one of
// `allowed_roots` (baker::pathUnderRoots: `..` and links resolved; a relative path against the
// working directory, as the bake read it); one outside gives black and a `warning` naming it
// ("...: environment file X recorded in the volume is outside the scene folder; not opened
// (pass --env to use it)..."), as does a recorded file that no longer loads.
Result<Environment> recordedEnvironment(const BakeMetadata& metadata, const std::string& source,
                                        const std::vector<std::filesystem::path>& allowed_roots,
                                        std::string& warning);

// One 2^3 volume of zeros over the scene's bounds: the volume set a renderer needs when the
// scene is shown without a .pvol (the dynamic GI alone, FrameSettings::bakedLight false).
Result<Volume> placeholderVolume(const baker::Scene& scene);

} // namespace probekit::viewer
