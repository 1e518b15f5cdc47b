#include "gi_twin.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "probekit/formats/lpv_transport.hpp"

namespace probekit::runtime {
namespace {

constexpr double kPi = 3.14159265358979323846;
const float kSqrtFourPi = float(std::sqrt(4.0 * kPi));

// The shared transport (formats/lpv_transport.hpp, as the offline LPV's).
using lpv::basisL1;
using lpv::Face;
using lpv::faces;
using lpv::kBandOneIndex;
using lpv::kDirections;

bool inside(glm::ivec3 c, int n) {
    return glm::all(glm::greaterThanEqual(c, glm::ivec3(0))) &&
           glm::all(glm::lessThan(c, glm::ivec3(n)));
}

// The LPV cell holding world point p, or -1 outside the cascade.
int32_t targetCell(const GiCascadeLayout& layout, glm::vec3 p) {
    const glm::ivec3 c(glm::floor((p - layout.origin) / layout.cellSize));
    return inside(c, layout.cells) ? int32_t(giCellIndex(layout, c)) : -1;
}

// L1 radiance of `field` at p, trilinear between cell centres, clamped at the border.
sh::ShRgb sampleField(const GiCascadeLayout& layout, const GiField& field, glm::vec3 p) {
    const int n = layout.cells;
    const glm::vec3 g = glm::clamp((p - layout.origin) / layout.cellSize - 0.5f, glm::vec3(0.0f),
                                   glm::vec3(float(n - 1)));
    const glm::ivec3 i0 = glm::min(glm::ivec3(glm::floor(g)), glm::ivec3(n - 1));
    const glm::ivec3 i1 = glm::min(i0 + 1, glm::ivec3(n - 1));
    const glm::vec3 t = g - glm::vec3(i0);
    sh::ShRgb out;
    for (int corner = 0; corner < 8; ++corner) {
        const glm::ivec3 pick((corner & 1) ? i1.x : i0.x, (corner & 2) ? i1.y : i0.y,
                              (corner & 4) ? i1.z : i0.z);
        const float w = ((corner & 1) ? t.x : 1.0f - t.x) * ((corner & 2) ? t.y : 1.0f - t.y) *
                        ((corner & 4) ? t.z : 1.0f - t.z);
        const size_t cell = giCellIndex(layout, pick);
        for (int k = 0; k < 4; ++k) {
            for (int ch = 0; ch < 3; ++ch) {
                out.rgb[size_t(k)][ch] += w * field.at(cell, k, ch);
            }
        }
    }
    return out;
}

// L1 irradiance facing unit m, clamped at 0.
glm::vec3 irradianceL1(const sh::ShRgb& radiance, glm::vec3 m) {
    const std::array<float, 4> y = basisL1(m);
    glm::vec3 e = sh::kCosineLobe[0] * y[0] * radiance.rgb[0];
    for (int k = 1; k < 4; ++k) {
        e += sh::kCosineLobe[1] * y[size_t(k)] * radiance.rgb[size_t(k)];
    }
    return glm::max(e, glm::vec3(0.0f));
}

// Stage 2's shared part: each side's target and flux from E(m).
template <class Irradiance>
std::vector<GiSurfaceLight> surfaceLights(const GiCascadeLayout& layout,
                                          std::span<const GiGeometryCell> geometry,
                                          const Irradiance& irradiance) {
    std::vector<GiSurfaceLight> out(geometry.size());
    const int gv = layout.geometryCells();
    for (int z = 0; z < gv; ++z) {
        for (int y = 0; y < gv; ++y) {
            for (int x = 0; x < gv; ++x) {
                const glm::ivec3 g(x, y, z);
                const size_t gi = layout.geometryIndex(g);
                const GiSurface surface = giSurfaceOf(layout, geometry[gi], g);
                GiSurfaceLight& light = out[gi];
                light.normal = surface.normal;
                if (!(surface.area > 0.0f)) {
                    continue;
                }
                for (int side = 0; side < 2; ++side) {
                    const glm::vec3 m = side == 0 ? surface.normal : -surface.normal;
                    const glm::vec3 at = surface.position + 0.5f * layout.cellSize * m;
                    light.target[size_t(side)] = targetCell(layout, at);
                    if (light.target[size_t(side)] < 0) {
                        continue;
                    }
                    light.flux[size_t(side)] =
                        surface.area * surface.albedo * irradiance(surface, g, m, at);
                }
            }
        }
    }
    return out;
}

} // namespace

GiSurface giSurfaceOf(const GiCascadeLayout& layout, const GiGeometryCell& cell, glm::ivec3 g) {
    GiSurface s;
    if (cell.area <= 0) {
        return s;
    }
    const float area = float(cell.area) / kGiFixedScale;
    const float inv_area = 1.0f / area;
    const float face = layout.cellSize * layout.cellSize;
    // Each side reflects with the area facing it: a closed thin box has both faces in the cell
    // (front and back equal), a single two-sided quad only one, and either way a side's light
    // falls on one face's area.
    const float front = float(cell.frontArea) / kGiFixedScale;
    s.area = std::max(front, area - front) * face;
    glm::vec3 normal;
    glm::vec3 offset;
    for (int ch = 0; ch < 3; ++ch) {
        s.albedo[ch] = float(cell.albedoArea[size_t(ch)]) / kGiFixedScale * inv_area;
        normal[ch] = float(cell.normalArea[size_t(ch)]) / kGiFixedScale;
        offset[ch] = float(cell.offsetArea[size_t(ch)]) / kGiFixedScale * inv_area;
    }
    const float length = glm::length(normal);
    // Opposite normals that cancel (a wall's two faces canonicalise alike, so only curved or
    // cornered surfaces get here): no orientation, no injection.
    if (!(length > 1e-3f * area)) {
        s.area = 0.0f;
        return s;
    }
    s.normal = normal / length;
    s.position = layout.origin + (glm::vec3(g) + offset) * layout.cellSize;
    return s;
}

float giTransmittance(const GiCascadeLayout& layout, std::span<const GiGeometryCell> geometry,
                      glm::vec3 from, glm::vec3 direction, float distance, glm::ivec3 skip) {
    const float s = layout.cellSize;
    const int gv = layout.geometryCells();
    float transmittance = 1.0f;
    glm::ivec3 previous = skip;
    for (int k = 1; float(k) * s < distance; ++k) {
        const glm::vec3 p = from + direction * (s * float(k));
        const glm::ivec3 g(glm::floor((p - layout.origin) / s + 0.5f));
        if (!inside(g, gv)) {
            break;
        }
        if (g == skip || g == previous) {
            continue;
        }
        previous = g;
        const float b = giCellPotential(geometry[layout.geometryIndex(g)], direction);
        transmittance *= 1.0f - std::clamp(b, 0.0f, 1.0f);
        if (transmittance <= 0.0f) {
            break;
        }
    }
    return transmittance;
}

std::vector<GiSurfaceLight> giSurfaceLightsDirect(const GiCascadeLayout& layout,
                                                  std::span<const GiGeometryCell> geometry,
                                                  std::span<const PunctualLight> lights) {
    return surfaceLights(layout, geometry,
                         [&](const GiSurface& surface, glm::ivec3 g, glm::vec3 m, glm::vec3) {
                             glm::vec3 e(0.0f);
                             for (const PunctualLight& light : lights) {
                                 const auto to = directionToLight(light, surface.position);
                                 if (!to) {
                                     continue;
                                 }
                                 const glm::vec3 facing = irradianceAt(light, surface.position, m);
                                 if (facing == glm::vec3(0.0f)) {
                                     continue;
                                 }
                                 e += facing * giTransmittance(layout, geometry, surface.position,
                                                               to->direction, to->distance, g);
                             }
                             return e;
                         });
}

std::vector<GiSurfaceLight> giSurfaceLightsBounce(const GiCascadeLayout& layout,
                                                  std::span<const GiGeometryCell> geometry,
                                                  const GiField& previous) {
    return surfaceLights(layout, geometry,
                         [&](const GiSurface&, glm::ivec3, glm::vec3 m, glm::vec3 at) {
                             return irradianceL1(sampleField(layout, previous, at), m);
                         });
}

std::array<std::array<glm::vec3, 4>, 6> giBorderSky(const sh::ShRgb& sky) {
    std::array<std::array<glm::vec3, 4>, 6> out{};
    constexpr int kDirectionsCount = 1024;
    const float weight = 4.0f * float(kPi) / float(kDirectionsCount);
    for (int i = 0; i < kDirectionsCount; ++i) {
        // Light travelling along w comes from the sky in direction -w.
        const glm::vec3 w = sh::fibonacciDirection(i, kDirectionsCount);
        const sh::Coeffs y = sh::evalBasis(-w);
        glm::vec3 radiance(0.0f);
        for (int k = 0; k < sh::kMaxCoefficients; ++k) {
            radiance += y[size_t(k)] * sky.rgb[size_t(k)];
        }
        radiance = glm::max(radiance, glm::vec3(0.0f));
        const std::array<float, 4> yw = basisL1(w);
        for (int d = 0; d < 6; ++d) {
            const float c = glm::dot(w, glm::vec3(kDirections[size_t(d)]));
            if (c > 0.0f) {
                for (int k = 0; k < 4; ++k) {
                    out[size_t(d)][size_t(k)] += (weight * c * yw[size_t(k)]) * radiance;
                }
            }
        }
    }
    return out;
}

GiField giInject(const GiCascadeLayout& layout, std::span<const GiSurfaceLight> surfaces,
                 const std::array<std::array<glm::vec3, 4>, 6>* border_sky) {
    const int n = layout.cells;
    GiField field(giCellCount(layout));
    const float face = layout.cellSize * layout.cellSize;
    for (int z = 0; z < n; ++z) {
        for (int y = 0; y < n; ++y) {
            for (int x = 0; x < n; ++x) {
                const glm::ivec3 c(x, y, z);
                const auto ci = int32_t(giCellIndex(layout, c));
                std::array<glm::vec3, 4> sum{};
                for (int dz = -1; dz <= 1; ++dz) {
                    for (int dy = -1; dy <= 1; ++dy) {
                        for (int dx = -1; dx <= 1; ++dx) {
                            const glm::ivec3 g = c + glm::ivec3(dx, dy, dz);
                            if (!inside(g, layout.geometryCells())) {
                                continue;
                            }
                            const GiSurfaceLight& s = surfaces[layout.geometryIndex(g)];
                            for (int side = 0; side < 2; ++side) {
                                if (s.target[size_t(side)] != ci) {
                                    continue;
                                }
                                const glm::vec3 m = side == 0 ? s.normal : -s.normal;
                                const std::array<float, 4> ym = basisL1(m);
                                const glm::vec3 flux = s.flux[size_t(side)];
                                sum[0] += ym[0] * flux;
                                for (int k = 1; k < 4; ++k) {
                                    sum[size_t(k)] += (2.0f / 3.0f * ym[size_t(k)]) * flux;
                                }
                            }
                        }
                    }
                }
                if (border_sky) {
                    for (int d = 0; d < 6; ++d) {
                        // Light travelling along d enters through the low side for a positive d.
                        const int axis = d / 2;
                        const int layer = kDirections[size_t(d)][axis] > 0 ? 0 : n - 1;
                        if (c[axis] == layer) {
                            for (int k = 0; k < 4; ++k) {
                                sum[size_t(k)] += face * (*border_sky)[size_t(d)][size_t(k)];
                            }
                        }
                    }
                }
                for (int k = 0; k < 4; ++k) {
                    for (int ch = 0; ch < 3; ++ch) {
                        field.at(size_t(ci), k, ch) = sum[size_t(k)][ch];
                    }
                }
            }
        }
    }
    return field;
}

namespace {

// keep_f of every transfer (source cell, d, f), index (source x 6 + d) x 5 + f: the geometry
// does not change during an update, so giUpdateCascade computes it once.
std::vector<float> transferKeep(const GiCascadeLayout& layout,
                                std::span<const GiGeometryCell> geometry, float weight) {
    const int n = layout.cells;
    std::vector<float> keep(giCellCount(layout) * 30, weight);
    for (int z = 0; z < n; ++z) {
        for (int y = 0; y < n; ++y) {
            for (int x = 0; x < n; ++x) {
                const glm::ivec3 src(x, y, z);
                const size_t si = giCellIndex(layout, src);
                for (int d = 0; d < 6; ++d) {
                    if (!inside(src + kDirections[size_t(d)], n)) {
                        continue;
                    }
                    for (int f = 0; f < 5; ++f) {
                        const float potential = giFacePotential(
                            layout, geometry, src, d, faces()[size_t(d)][size_t(f)].direction);
                        keep[(si * 6 + size_t(d)) * 5 + size_t(f)] =
                            weight * (1.0f - std::clamp(potential, 0.0f, 1.0f));
                    }
                }
            }
        }
    }
    return keep;
}

glm::vec3 propagateWithKeep(const GiCascadeLayout& layout, std::span<const float> keep_table,
                            const GiField& current, glm::vec3 current_scale, GiField& next,
                            std::vector<float>& crossing) {
    const int n = layout.cells;
    const size_t count = giCellCount(layout);
    next = GiField(count);
    crossing.resize(18 * count, 0.0f);
    glm::dvec3 kept(0.0);
    glm::dvec3 dropped(0.0);
    for (int z = 0; z < n; ++z) {
        for (int y = 0; y < n; ++y) {
            for (int x = 0; x < n; ++x) {
                const glm::ivec3 c(x, y, z);
                const size_t ci = giCellIndex(layout, c);
                std::array<glm::vec3, 4> sum{};
                for (int d = 0; d < 6; ++d) {
                    const glm::ivec3 src = c - kDirections[size_t(d)];
                    if (!inside(src, n)) {
                        continue;
                    }
                    const size_t si = giCellIndex(layout, src);
                    std::array<glm::vec3, 4> source;
                    for (int k = 0; k < 4; ++k) {
                        for (int ch = 0; ch < 3; ++ch) {
                            source[size_t(k)][ch] = current.at(si, k, ch) * current_scale[ch];
                        }
                    }
                    glm::vec3 crossed(0.0f);
                    for (int f = 0; f < 5; ++f) {
                        const Face& face = faces()[size_t(d)][size_t(f)];
                        const float keep = keep_table[(si * 6 + size_t(d)) * 5 + size_t(f)];
                        const std::array<float, 4> yf = basisL1(face.direction);
                        glm::vec3 along = yf[0] * source[0];
                        for (int k = 1; k < 4; ++k) {
                            along += yf[size_t(k)] * source[size_t(k)];
                        }
                        const glm::vec3 flux = (keep * face.solidAngle) * along;
                        crossed += flux;
                        for (int k = 0; k < 4; ++k) {
                            sum[size_t(k)] += yf[size_t(k)] * flux;
                        }
                    }
                    for (int ch = 0; ch < 3; ++ch) {
                        crossing[(3 * size_t(d) + size_t(ch)) * count + ci] += crossed[ch];
                    }
                }
                for (int ch = 0; ch < 3; ++ch) {
                    if (sum[0][ch] < 0.0f) {
                        dropped[ch] += double(kSqrtFourPi * sum[0][ch]);
                        continue;
                    }
                    kept[ch] += double(kSqrtFourPi * sum[0][ch]);
                    for (int k = 0; k < 4; ++k) {
                        next.at(ci, k, ch) = sum[size_t(k)][ch];
                    }
                }
            }
        }
    }
    glm::vec3 scale(1.0f);
    for (int ch = 0; ch < 3; ++ch) {
        if (kept[ch] > 0.0 && dropped[ch] < 0.0) {
            scale[ch] = float((kept[ch] + dropped[ch]) / kept[ch]);
        }
    }
    return scale;
}

} // namespace

glm::vec3 giPropagateStep(const GiCascadeLayout& layout, std::span<const GiGeometryCell> geometry,
                          float weight, const GiField& current, glm::vec3 current_scale,
                          GiField& next, std::vector<float>& crossing) {
    return propagateWithKeep(layout, transferKeep(layout, geometry, weight), current, current_scale,
                             next, crossing);
}

void giResolve(const GiCascadeLayout& layout, const std::vector<float>& crossing,
               GiField& radiance) {
    const int n = layout.cells;
    const size_t count = giCellCount(layout);
    const float inv_area = 1.0f / (layout.cellSize * layout.cellSize);
    for (int z = 0; z < n; ++z) {
        for (int y = 0; y < n; ++y) {
            for (int x = 0; x < n; ++x) {
                const glm::ivec3 c(x, y, z);
                const size_t i = giCellIndex(layout, c);
                std::array<glm::vec3, 6> e{};
                for (int d = 0; d < 6; ++d) {
                    e[size_t(d)] = lpv::oneSidedIrradiance(
                        c, d, inv_area, [&](glm::ivec3 q) { return inside(q, n); },
                        [&](glm::ivec3 q, int travel) {
                            const size_t k = giCellIndex(layout, q);
                            return glm::vec3(crossing[(3 * size_t(travel)) * count + k],
                                             crossing[(3 * size_t(travel) + 1) * count + k],
                                             crossing[(3 * size_t(travel) + 2) * count + k]);
                        });
                }
                const std::array<glm::vec3, 4> r = lpv::radianceFromOneSided(e);
                for (int k = 0; k < 4; ++k) {
                    for (int ch = 0; ch < 3; ++ch) {
                        radiance.at(i, k, ch) += r[size_t(k)][ch];
                    }
                }
            }
        }
    }
}

GiField giUpdateCascade(const GiCascadeLayout& layout, std::span<const GiGeometryCell> geometry,
                        const GiCascadeInputs& inputs) {
    const size_t count = giCellCount(layout);
    GiField total(count);
    GiField previous;
    const std::vector<float> keep = transferKeep(layout, geometry, inputs.propagationWeight);
    std::array<std::array<glm::vec3, 4>, 6> border{};
    if (inputs.sky) {
        border = giBorderSky(*inputs.sky);
    }
    for (uint32_t bounce = 0; bounce < std::max(1u, inputs.bounces); ++bounce) {
        const std::vector<GiSurfaceLight> surfaces =
            bounce == 0 ? giSurfaceLightsDirect(layout, geometry, inputs.lights)
                        : giSurfaceLightsBounce(layout, geometry, previous);
        GiField current = giInject(layout, surfaces, bounce == 0 && inputs.sky ? &border : nullptr);
        GiField next;
        std::vector<float> crossing(18 * count, 0.0f);
        glm::vec3 scale(1.0f);
        for (uint32_t it = 0; it < inputs.iterations; ++it) {
            scale = propagateWithKeep(layout, keep, current, scale, next, crossing);
            std::swap(current, next);
        }
        GiField pass(count);
        giResolve(layout, crossing, pass);
        for (size_t i = 0; i < total.data.size(); ++i) {
            total.data[i] += pass.data[i];
        }
        previous = std::move(pass);
    }
    return total;
}

void giZonal(sh::ShRgb& radiance) {
    for (int ch = 0; ch < 3; ++ch) {
        const float l00 = radiance.rgb[0][ch];
        const glm::vec3 l1(radiance.rgb[3][ch], radiance.rgb[1][ch], radiance.rgb[2][ch]);
        const float length = glm::length(l1);
        if (!(l00 > 0.0f) || !(length > 0.0f)) {
            continue;
        }
        const float r = std::min(1.0f, length / (std::sqrt(3.0f) * l00));
        const float z = std::sqrt(5.0f) * l00 * r * r;
        const sh::Coeffs y = sh::evalBasis(l1 / length);
        const float to_basis = std::sqrt(4.0f * float(kPi) / 5.0f);
        for (int k = 4; k < 9; ++k) {
            radiance.rgb[size_t(k)][ch] = z * to_basis * y[size_t(k)];
        }
    }
}

sh::ShRgb giSampleRadiance(std::span<const GiCascadeLayout> layouts,
                           std::span<const GiField> radiance, float fade_cells, bool zonal,
                           glm::vec3 p) {
    sh::ShRgb result;
    for (size_t j = layouts.size(); j-- > 0;) {
        const GiCascadeLayout& l = layouts[j];
        const glm::vec3 lo = p - l.origin;
        const glm::vec3 hi = l.origin + float(l.cells) * l.cellSize - p;
        const float inside_distance = std::min({lo.x, lo.y, lo.z, hi.x, hi.y, hi.z});
        const float band = fade_cells * l.cellSize;
        const float w = band > 0.0f ? std::clamp(inside_distance / band, 0.0f, 1.0f)
                                    : (inside_distance >= 0.0f ? 1.0f : 0.0f);
        if (w <= 0.0f) {
            continue;
        }
        const sh::ShRgb fine = sampleField(l, radiance[j], p);
        for (int k = 0; k < 4; ++k) {
            result.rgb[size_t(k)] = (1.0f - w) * result.rgb[size_t(k)] + w * fine.rgb[size_t(k)];
        }
    }
    if (zonal) {
        giZonal(result);
    }
    return result;
}

namespace {
size_t nearestGeometryCell(const GiCascadeLayout& layout, glm::vec3 p) {
    const int gv = layout.geometryCells();
    const glm::ivec3 g =
        glm::clamp(glm::ivec3(glm::floor((p - layout.origin) / layout.cellSize + 0.5f)),
                   glm::ivec3(0), glm::ivec3(gv - 1));
    return layout.geometryIndex(g);
}
} // namespace

float giSunVisibility(const GiCascadeLayout& layout, std::span<const GiGeometryCell> geometry,
                      glm::vec3 p, glm::vec3 n, glm::vec3 to_light) {
    return giTransmittance(layout, geometry, p + 0.5f * layout.cellSize * n, to_light,
                           std::numeric_limits<float>::infinity(), glm::ivec3(-1));
}

glm::vec3 giGeometryColour(const GiCascadeLayout& layout, std::span<const GiGeometryCell> geometry,
                           glm::vec3 p) {
    const GiGeometryCell& cell = geometry[nearestGeometryCell(layout, p)];
    const float area = float(cell.area) / kGiFixedScale;
    if (!(area > 0.0f)) {
        return glm::vec3(0.0f);
    }
    const glm::vec3 albedo_area(float(cell.albedoArea[0]) / kGiFixedScale,
                                float(cell.albedoArea[1]) / kGiFixedScale,
                                float(cell.albedoArea[2]) / kGiFixedScale);
    return albedo_area / area * std::min(1.0f, area);
}

float giOcclusion(const GiCascadeLayout& layout, std::span<const GiGeometryCell> geometry,
                  glm::vec3 p, glm::vec3 n) {
    const GiGeometryCell& cell =
        geometry[nearestGeometryCell(layout, p + 0.5f * layout.cellSize * n)];
    float blocked = 0.0f;
    for (const glm::ivec3& d : kDirections) {
        blocked += std::clamp(giCellPotential(cell, glm::vec3(d)), 0.0f, 1.0f);
    }
    return 1.0f - blocked / 6.0f;
}

} // namespace probekit::runtime
