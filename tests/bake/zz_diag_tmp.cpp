// TEMPORARY diagnostic, not committed.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include "bake_test_support.hpp"
#include "path_integrator.hpp"
#include "ray_tracer.hpp"
#include "probekit/baker/surface_reference.hpp"
#include "probekit/runtime/renderer.hpp"
#include "probekit/runtime/surface_error.hpp"

using namespace probekit;
TEST(ZZDiag, L2Floor) {
    const char* env = std::getenv("PK_DIAG");
    if (!env) GTEST_SKIP();
    baker::Scene scene = test::generatedScene("cornell");
    const uint32_t W = 80, H = 60;
    runtime::Camera cam = runtime::frameBounds(scene.bounds, 40.0f, float(W) / H, glm::vec3(0, 0, -1));
    std::vector<baker::SurfaceRay> rays;
    for (uint32_t y = 0; y < H; ++y)
        for (uint32_t x = 0; x < W; ++x)
            rays.push_back({cam.eye, runtime::pixelDirection(cam, W, H, glm::vec2(x + 0.5f, y + 0.5f))});
    baker::SurfaceReferenceSettings rs; rs.samples = 8192;
    auto ref = baker::traceSurfaceReference(scene, rays, rs).value();
    auto tracer = baker::RayTracer::create(scene).value();
    baker::PathSettings ps; ps.samples = 8192;
    baker::PathIntegrator integ(scene, *tracer, ps, sh::Order::L2);
    runtime::SurfaceReferenceImage img; img.width = W; img.height = H;
    for (auto& s : ref.samples) { img.hit.push_back(s.hit); img.position.push_back(s.position); img.normal.push_back(s.normal); img.irradiance.push_back(s.irradiance); img.standardError.push_back(s.standardError);}
    for (float off : {0.002f}) {
        std::vector<glm::vec3> test(ref.samples.size());
        for (size_t i = 0; i < ref.samples.size(); ++i) {
            if (!ref.samples[i].hit) continue;
            auto p = integ.bakeProbe(ref.samples[i].position + off * ref.samples[i].normal, 7, 0, i);
            test[i] = sh::irradiance(p.sh, sh::Order::L2, ref.samples[i].normal);
        }
        auto e = runtime::compareSurface(test, img).value();
        std::printf("offset %.3f: median %.4f mean %.4f under %.4f over %.4f neg %.4f noisefloor %.4f\n", off, e.medianAbsError, e.meanRatio, e.shareUnderHalf, e.shareOverTwo, e.shareNegative, e.noiseFloor);
    }
}
