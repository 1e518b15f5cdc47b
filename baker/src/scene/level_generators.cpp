// The game levels among the bundled scenes (generators.hpp: arena, arena-sealed): a 65 m arena
// of the kind issue 29's users bake, built of closed boxes as level editors build them.
#include <algorithm>
#include <vector>

#include "scene_spec.hpp"

namespace probekit::baker::generated {

namespace {

enum Material : int { Concrete, Plaster, Brick, Stone, Wood, Moss, MaterialCount };

constexpr float kHalf = 32.5f;       // the level spans -32.5..32.5 m in x and z
constexpr float kYard = 12.0f;       // the open yard spans -12..12 m
constexpr float kStorey = 4.0f;      // room height; the roofs are 0.3 m slabs on top
constexpr float kOuterHeight = 8.0f; // the outer walls

// A gap in a wall: centred at `at` along it, `width` wide, `height` high from the wall's foot.
// An arch steps its top corners in by a fifth of the width, 0.5 m down.
struct Opening {
    float at;
    float width;
    float height;
    bool arch = false;
};

class LevelBuilder {
public:
    LevelBuilder() {
        m_spec.materials = {
            {"concrete", glm::vec3(0.45f)},          {"plaster", glm::vec3(0.65f, 0.63f, 0.6f)},
            {"brick", glm::vec3(0.5f, 0.3f, 0.25f)}, {"stone", glm::vec3(0.4f, 0.4f, 0.42f)},
            {"wood", glm::vec3(0.45f, 0.32f, 0.2f)}, {"moss", glm::vec3(0.3f, 0.45f, 0.3f)}};
        m_spec.meshes.resize(MaterialCount);
        for (int m = 0; m < MaterialCount; ++m) {
            m_spec.meshes[size_t(m)].material = m;
        }
    }

    void solid(Material m, glm::vec3 lo, glm::vec3 hi) { m_spec.meshes[size_t(m)].box(lo, hi); }

    // A wall of thickness `thick` centred on `across` (z for axis 0, x for axis 2), running
    // from `from` to `to` along the axis, from y0 to y1, with openings.
    void wall(Material m, int axis, float from, float to, float across, float thick, float y0,
              float y1, std::vector<Opening> openings = {}) {
        std::sort(openings.begin(), openings.end(),
                  [](const Opening& a, const Opening& b) { return a.at < b.at; });
        float start = from;
        for (const Opening& o : openings) {
            const float lo = o.at - 0.5f * o.width;
            const float hi = o.at + 0.5f * o.width;
            span(m, axis, start, lo, across, thick, y0, y1);
            span(m, axis, lo, hi, across, thick, y0 + o.height, y1); // lintel
            if (o.arch) {
                const float step = 0.2f * o.width;
                const float y = y0 + o.height - 0.5f;
                span(m, axis, lo, lo + step, across, thick, y, y0 + o.height);
                span(m, axis, hi - step, hi, across, thick, y, y0 + o.height);
            }
            start = hi;
        }
        span(m, axis, start, to, across, thick, y0, y1);
    }

    void point(glm::vec3 p, glm::vec3 colour, float intensity) {
        m_spec.lights.push_back({p, colour, intensity});
    }
    void spot(glm::vec3 p, glm::vec3 target, glm::vec3 colour, float intensity) {
        m_spec.spots.push_back({p, glm::normalize(target - p), colour, intensity, 25.0f, 35.0f});
    }

    SceneSpec take() { return std::move(m_spec); }

private:
    void span(Material m, int axis, float a, float b, float across, float thick, float y0,
              float y1) {
        if (b - a <= 1e-4f || y1 - y0 <= 1e-4f) {
            return;
        }
        const float c0 = across - 0.5f * thick;
        const float c1 = across + 0.5f * thick;
        if (axis == 0) {
            solid(m, glm::vec3(a, y0, c0), glm::vec3(b, y1, c1));
        } else {
            solid(m, glm::vec3(c0, y0, a), glm::vec3(c1, y1, b));
        }
    }

    SceneSpec m_spec;
};

// Ground, outer walls, the yard's walls with arches and doors, the walls between the eight rooms
// of the band around it, the north corridor and a thin partition.
void buildWalls(LevelBuilder& b) {
    const float in = kHalf - 0.5f; // inner face of the outer walls
    b.solid(Concrete, glm::vec3(-kHalf, -0.5f, -kHalf), glm::vec3(kHalf, 0.0f, kHalf));
    b.solid(Brick, glm::vec3(-kHalf, 0.0f, -kHalf), glm::vec3(kHalf, kOuterHeight, -in));
    b.solid(Brick, glm::vec3(-kHalf, 0.0f, in), glm::vec3(kHalf, kOuterHeight, kHalf));
    b.solid(Brick, glm::vec3(-kHalf, 0.0f, -in), glm::vec3(-in, kOuterHeight, in));
    b.solid(Brick, glm::vec3(in, 0.0f, -in), glm::vec3(kHalf, kOuterHeight, in));
    const std::vector<Opening> yard_side = {
        {-7.0f, 1.6f, 2.4f}, {0.0f, 3.0f, 3.2f, true}, {7.0f, 1.6f, 2.4f}};
    for (const float side : {-kYard, kYard}) {
        b.wall(Moss, 0, -kYard - 0.15f, kYard + 0.15f, side, 0.3f, 0.0f, kStorey, yard_side);
        b.wall(Moss, 2, -kYard + 0.15f, kYard - 0.15f, side, 0.3f, 0.0f, kStorey, yard_side);
        // Between the corner rooms and the side rooms: a door in the middle of each.
        for (const float sign : {-1.0f, 1.0f}) {
            const float from = sign < 0 ? -in : kYard + 0.15f;
            const float to = sign < 0 ? -kYard - 0.15f : in;
            const float middle = sign * 0.5f * (kYard + in);
            b.wall(Plaster, 2, from, to, side, 0.2f, 0.0f, kStorey, {{middle, 1.2f, 2.2f}});
            b.wall(Plaster, 0, from, to, side, 0.2f, 0.0f, kStorey, {{middle, 1.2f, 2.2f}});
        }
    }
    // The north corridor, 3 m wide along the outer wall, through three rooms.
    b.wall(Plaster, 0, -in, in, in - 3.1f, 0.2f, 0.0f, kStorey,
           {{-22.0f, 1.2f, 2.2f},
            {-8.0f, 2.4f, 3.0f, true},
            {0.0f, 1.2f, 2.2f},
            {8.0f, 2.4f, 3.0f, true},
            {22.0f, 1.2f, 2.2f}});
    // A thin partition (5 cm) splitting the south side room, a doorway at its yard end.
    b.wall(Plaster, 2, -in, -kYard - 0.15f, 0.0f, 0.05f, 0.0f, kStorey, {{-14.0f, 0.9f, 2.1f}});
}

// The roofs of the band's rooms, the stair from the yard onto the south roof, columns, a plinth,
// lamp posts and crates.
void buildProps(LevelBuilder& b) {
    const float in = kHalf - 0.5f;
    const float top = kStorey + 0.3f;
    const float edge = kYard + 0.15f;
    b.solid(Stone, glm::vec3(-in, kStorey, -in), glm::vec3(in, top, -edge));
    b.solid(Stone, glm::vec3(-in, kStorey, edge), glm::vec3(in, top, in));
    b.solid(Stone, glm::vec3(-in, kStorey, -edge), glm::vec3(-edge, top, edge));
    b.solid(Stone, glm::vec3(edge, kStorey, -edge), glm::vec3(in, top, edge));
    constexpr int kSteps = 16;
    for (int i = 0; i < kSteps; ++i) { // rising towards the south yard wall
        const float z1 = -kYard + 0.15f + 0.49f * float(kSteps - i);
        b.solid(Stone, glm::vec3(4.0f, 0.0f, z1 - 0.49f),
                glm::vec3(6.0f, top * float(i + 1) / float(kSteps), z1));
    }
    for (const float x : {-6.0f, 6.0f}) {
        for (const float z : {-6.0f, 6.0f}) {
            b.solid(Stone, glm::vec3(x - 0.3f, 0.0f, z - 0.3f),
                    glm::vec3(x + 0.3f, 3.5f, z + 0.3f));
            b.solid(Wood, glm::vec3(1.6f * x - 0.1f, 0.0f, 1.6f * z - 0.1f),
                    glm::vec3(1.6f * x + 0.1f, 6.0f, 1.6f * z + 0.1f)); // lamp post
        }
    }
    b.solid(Stone, glm::vec3(-1.5f, 0.0f, -1.5f), glm::vec3(1.5f, 1.0f, 1.5f));
    // Three crates per room of the band, in a fixed pattern.
    for (int i = 0; i < 24; ++i) {
        const float angle = 0.2618f * float(i); // 15 degrees apart
        const float r = 16.0f + 12.0f * float(i % 3) / 2.0f;
        const glm::vec3 c(r * std::cos(angle), 0.0f, r * std::sin(angle));
        const float s = 0.5f + 0.25f * float(i % 2);
        b.solid(Wood, glm::vec3(c.x - s, 0.0f, c.z - s), glm::vec3(c.x + s, 2.0f * s, c.z + s));
    }
}

// 32 lights: two in each of the eight rooms, four in the corridor, eight wall lamps and four
// spots on posts over the yard.
void buildLights(LevelBuilder& b) {
    const glm::vec3 warm(1.0f, 0.85f, 0.65f);
    const glm::vec3 cool(0.75f, 0.85f, 1.0f);
    const float mid = 0.5f * (kYard + kHalf - 3.5f); // room centres in the band
    for (const float x : {-1.0f, 0.0f, 1.0f}) {
        for (const float z : {-1.0f, 0.0f, 1.0f}) {
            if (x == 0.0f && z == 0.0f) {
                continue;
            }
            const glm::vec3 centre(x * mid, 3.2f, z * mid);
            const glm::vec3 along = x != 0.0f ? glm::vec3(0.0f, 0.0f, 4.0f) : glm::vec3(4.0f, 0, 0);
            b.point(centre - along, warm, 30.0f);
            b.point(centre + along, z > 0.0f ? cool : warm, 30.0f);
        }
    }
    for (const float x : {-24.0f, -8.0f, 8.0f, 24.0f}) {
        b.point(glm::vec3(x, 3.0f, kHalf - 2.0f), warm, 10.0f);
    }
    for (const float at : {-9.5f, 9.5f}) {
        for (const float side : {-kYard + 0.5f, kYard - 0.5f}) {
            b.point(glm::vec3(at, 2.5f, side), warm, 15.0f);
            b.point(glm::vec3(side, 2.5f, at), cool, 15.0f);
        }
    }
    for (const float x : {-9.6f, 9.6f}) {
        for (const float z : {-9.6f, 9.6f}) {
            b.spot(glm::vec3(x, 6.2f, z), glm::vec3(0.3f * x, 0.0f, 0.3f * z), warm, 200.0f);
        }
    }
}

} // namespace

SceneSpec arenaLevel() {
    LevelBuilder b;
    buildWalls(b);
    buildProps(b);
    buildLights(b);
    return b.take();
}

SceneSpec arenaSealed() {
    LevelBuilder b;
    buildWalls(b);
    buildProps(b);
    buildLights(b);
    // A roof over everything on the outer walls: no sky reaches in.
    b.solid(Stone, glm::vec3(-kHalf, kOuterHeight, -kHalf),
            glm::vec3(kHalf, kOuterHeight + 0.5f, kHalf));
    return b.take();
}

} // namespace probekit::baker::generated
