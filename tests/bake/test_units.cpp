// Scenes not made for the baker: files in centimetres or millimetres (LoadOptions::scale, the
// implausible-size warning), a single closed object that automatic bounds would fill with
// invalid probes (automatic padding), and automatic resolutions that max_resolution caps (the
// note that says what was asked and what is used).
#include <algorithm>
#include <string>

#include <gtest/gtest.h>

#include "bake_test_support.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/generators.hpp"

using namespace probekit;
using namespace probekit::baker;

namespace {

// Adds a closed box [lo, hi], 12 triangles wound outwards (front faces outside), and grows the
// bounds.
void addBox(Scene& s, glm::vec3 lo, glm::vec3 hi) {
    const uint32_t first = uint32_t(s.positions.size());
    for (int i = 0; i < 8; ++i) {
        s.positions.emplace_back(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
    }
    // Each face as two triangles, counter-clockwise seen from outside.
    const glm::uvec3 tris[] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                               {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
    for (const glm::uvec3& t : tris) {
        s.triangles.push_back(t + first);
    }
    s.uvs.resize(s.positions.size(), glm::vec2(0.0f));
    s.triangleMaterial.resize(s.triangles.size(), 0);
    s.triangleNode.resize(s.triangles.size(), -1);
    s.materials.resize(1);
    s.bounds = first == 0 ? grid::Aabb{lo, hi}
                          : grid::Aabb{glm::min(s.bounds.min, lo), glm::max(s.bounds.max, hi)};
}

void underConstantSky(Scene& s) {
    s.environment.type = Environment::Type::Constant;
    s.environment.constant = glm::vec3(1.0f);
}

// A closed cube [lo, hi]^3 in open space under a constant sky.
Scene closedCube(float lo, float hi) {
    Scene s;
    addBox(s, glm::vec3(lo), glm::vec3(hi));
    underConstantSky(s);
    return s;
}

// A sealed level built of solid blocks, as level editors make them: in a 12 x 3 x 12 m box, a
// floor and a ceiling slab, outer walls and a solid 9 x 9 m block leave an L-shaped corridor
// 2.5 m wide and 2 m high, closed at both ends. Most of the box is solid, as in a real level
// (61% of the test points of the arena map).
Scene sealedLevel() {
    Scene s;
    addBox(s, glm::vec3(0.0f), glm::vec3(12.0f, 0.5f, 12.0f));             // floor
    addBox(s, glm::vec3(0.0f, 2.5f, 0.0f), glm::vec3(12.0f, 3.0f, 12.0f)); // ceiling
    addBox(s, glm::vec3(0.0f, 0.5f, 0.0f), glm::vec3(0.5f, 2.5f, 12.0f));  // west wall
    addBox(s, glm::vec3(0.5f, 0.5f, 0.0f), glm::vec3(12.0f, 2.5f, 0.5f));  // south wall
    addBox(s, glm::vec3(3.0f, 0.5f, 3.0f), glm::vec3(12.0f, 2.5f, 12.0f)); // the block
    addBox(s, glm::vec3(11.5f, 0.5f, 0.5f), glm::vec3(12.0f, 2.5f, 3.0f)); // east end
    addBox(s, glm::vec3(0.5f, 0.5f, 11.5f), glm::vec3(3.0f, 2.5f, 12.0f)); // north end
    underConstantSky(s);
    return s;
}

bool anyNoteHas(const std::vector<std::string>& notes, const std::string& text) {
    return std::any_of(notes.begin(), notes.end(),
                       [&](const std::string& n) { return n.find(text) != std::string::npos; });
}

// A single closed object: automatic bounds hug it, so without padding every probe is inside.
TEST(AutoPadding, AClosedObjectGetsHalfItsSizeOnEverySide) {
    const Scene cube = closedCube(0.0f, 1.0f);
    Result<VolumePlan> plan = planVolumes(cube, BakeConfig{});
    ASSERT_TRUE(plan.ok()) << plan.error().message;
    ASSERT_EQ(plan.value().padding.size(), 1u);
    EXPECT_FLOAT_EQ(plan.value().padding[0], kAutoPaddingGrowth * 1.0f);
    EXPECT_TRUE(anyNoteHas(plan.value().notes, "a closed object")) << plan.value().notes.size();
    const grid::Aabb box = plan.value().volumes[0].grid.bounds();
    EXPECT_FLOAT_EQ(box.min.x, -0.5f);
    EXPECT_FLOAT_EQ(box.max.y, 1.5f);

    // Baked, most probes lie outside the cube: the cube is 1/8 of the box, so at most that
    // share plus the probes on its faces may be invalid; before the padding every one was.
    BakeConfig config;
    config.path.samples = 64;
    Result<BakeResult> baked = bake(cube, config);
    ASSERT_TRUE(baked.ok()) << baked.error().message;
    const double invalid =
        double(baked.value().stats.invalidProbes) / double(baked.value().stats.probes);
    EXPECT_LE(invalid, 0.2) << baked.value().stats.invalidProbes << " of "
                            << baked.value().stats.probes;
    EXPECT_TRUE(anyNoteHas(baked.value().warnings, "a closed object"));

    // An explicit padding (0 too) is kept as given.
    BakeConfig zero;
    zero.volumes.push_back(VolumeConfig{});
    zero.volumes[0].bounds.padding = 0.0f;
    Result<VolumePlan> hugged = planVolumes(cube, zero);
    ASSERT_TRUE(hugged.ok());
    EXPECT_EQ(hugged.value().padding[0], 0.0f);
    EXPECT_TRUE(hugged.value().notes.empty());
    Result<BakeResult> inside = bake(cube, [&] {
        BakeConfig c = zero;
        c.path.samples = 64;
        c.dilate = false;
        c.relocate = false; // relocated, the probes within a cell of a face would be valid
        return c;
    }());
    ASSERT_TRUE(inside.ok());
    EXPECT_EQ(inside.value().stats.invalidProbes, inside.value().stats.probes);
}

// Rooms seen from inside (the bundled scenes) keep their bounds: their test points see front
// faces.
TEST(AutoPadding, RoomsAndOpenScenesAreNotPadded) {
    for (const char* name : {"cornell", "thin-wall", "courtyard"}) {
        SCOPED_TRACE(name);
        const Scene scene = test::generatedScene(name);
        Result<VolumePlan> plan = planVolumes(scene, BakeConfig{});
        ASSERT_TRUE(plan.ok()) << plan.error().message;
        EXPECT_EQ(plan.value().padding[0], 0.0f);
        EXPECT_FALSE(anyNoteHas(plan.value().notes, "closed object"));
        const grid::Aabb box = plan.value().volumes[0].grid.bounds();
        EXPECT_EQ(box.min, scene.bounds.min);
        EXPECT_EQ(box.max, scene.bounds.max);
    }
}

// A sealed level seen from its solid space is most of its box "inside" by the backface rule, like
// a closed object; padding it would put most probes outside the level (issue 29, item 7). Its
// open test points see walls all around, which no point outside a closed object does: an
// L-shaped object, whose notch holds open points, is still padded.
TEST(AutoPadding, ASealedLevelIsNotTakenForAClosedObject) {
    const Scene level = sealedLevel();
    Result<VolumePlan> plan = planVolumes(level, BakeConfig{});
    ASSERT_TRUE(plan.ok()) << plan.error().message;
    EXPECT_EQ(plan.value().padding[0], 0.0f);
    EXPECT_TRUE(anyNoteHas(plan.value().notes, "a level seen from its solid space"));
    EXPECT_FALSE(anyNoteHas(plan.value().notes, "closed object)"));

    Scene notched;
    addBox(notched, glm::vec3(0.0f), glm::vec3(2.0f, 1.0f, 1.0f));
    addBox(notched, glm::vec3(0.0f, 0.0f, 1.0f), glm::vec3(1.0f, 1.0f, 2.0f));
    underConstantSky(notched);
    Result<VolumePlan> object = planVolumes(notched, BakeConfig{});
    ASSERT_TRUE(object.ok()) << object.error().message;
    EXPECT_FLOAT_EQ(object.value().padding[0], kAutoPaddingGrowth * 2.0f);
    EXPECT_TRUE(anyNoteHas(object.value().notes, "a closed object"));

    // Lit only by the sky it is sealed from, the level bakes to zeros: said, not silent.
    BakeConfig config = test::sceneVolume(16, glm::uvec3(4));
    Result<BakeResult> dark = bake(level, config);
    ASSERT_TRUE(dark.ok()) << dark.error().message;
    EXPECT_TRUE(anyNoteHas(dark.value().warnings,
                           "volume 'volume': every probe is black: no light reaches any of them"));
    // The same level with a lamp in the corridor: no such warning.
    Scene lit = level;
    PunctualLight lamp;
    lamp.type = LightType::Point;
    lamp.position = glm::vec3(1.5f, 1.5f, 6.0f);
    lamp.intensity = glm::vec3(10.0f);
    lit.lights.push_back(lamp);
    Result<BakeResult> bright = bake(lit, config);
    ASSERT_TRUE(bright.ok()) << bright.error().message;
    EXPECT_FALSE(anyNoteHas(bright.value().warnings, "every probe is black"));
}

TEST(UnitScale, LoadingInCentimetresScalesLengthsNotLight) {
    const auto dir = test::tempDir("unit_scale");
    ASSERT_TRUE(writeGeneratedScene("thin-wall", dir / "wall.gltf").ok());
    const Scene metres = test::loadOrFail(dir / "wall.gltf");
    LoadOptions cm;
    cm.scale = 0.01f;
    Result<Scene> scaled = loadGltf(dir / "wall.gltf", cm);
    ASSERT_TRUE(scaled.ok()) << scaled.error().message;
    const Scene& s = scaled.value();
    EXPECT_EQ(s.unitScale, 0.01f);
    ASSERT_EQ(s.positions.size(), metres.positions.size());
    for (size_t i = 0; i < s.positions.size(); ++i) {
        EXPECT_EQ(s.positions[i], metres.positions[i] * 0.01f);
    }
    EXPECT_EQ(s.bounds.max, metres.bounds.max * 0.01f);
    ASSERT_EQ(s.lights.size(), metres.lights.size());
    ASSERT_FALSE(s.lights.empty());
    EXPECT_EQ(s.lights[0].position, metres.lights[0].position * 0.01f);
    EXPECT_EQ(s.lights[0].intensity, metres.lights[0].intensity); // W/sr: no length in it
    for (size_t n = 0; n < s.nodes.size(); ++n) {
        const glm::vec4 p = s.nodes[n].world * glm::vec4(1.0f, 2.0f, 3.0f, 1.0f);
        const glm::vec4 q = metres.nodes[n].world * glm::vec4(1.0f, 2.0f, 3.0f, 1.0f);
        EXPECT_NEAR(p.x, 0.01f * q.x, 1e-6f);
        EXPECT_NEAR(p.z, 0.01f * q.z, 1e-6f);
    }
    // 8 m x 2.5 m x 4 m at 1 cm per unit is 8 cm across: plausible, no warning.
    EXPECT_TRUE(implausibleSizeWarning(s, "wall.gltf").empty());
}

TEST(UnitScale, AScaleThatShrinksTheSceneUnderACentimetreIsRefused) {
    const auto dir = test::tempDir("unit_scale_small");
    const std::filesystem::path box = dir / "box.gltf";
    ASSERT_TRUE(writeGeneratedScene("cornell", box).ok());
    // The 0.5592 m box at 0.01 m per unit is 5.6 mm across: refused, naming the scale and the
    // size the file has at 1 m per unit (before, it baked 16% to 99% wrong with exit 0).
    LoadOptions tiny;
    tiny.scale = 0.01f;
    const Result<Scene> refused = loadGltf(box, tiny);
    ASSERT_FALSE(refused.ok());
    EXPECT_EQ(refused.error().message,
              box.string() + ": the scene is 0.005592 m across at 0.01 m per unit (--scale, or "
                             "scale in the config), less than 0.01 m, too small to bake (the "
                             "tracer's offsets and the bake's distances are lengths in metres): "
                             "at 1 m per unit it is 0.5592 m across");
    // 0.02 m per unit makes it 1.1 cm: loaded.
    LoadOptions small;
    small.scale = 0.02f;
    EXPECT_TRUE(loadGltf(box, small).ok());
    // A file whose own size is under 1 cm (a kilometre export) is refused with the scale that
    // fixes it.
    Scene km = test::loadOrFail(box);
    applyUnitScale(km, 1e-3f);
    const Result<void> km_refused = checkSceneSize(km, "km.gltf", 1.0f);
    ASSERT_FALSE(km_refused.ok());
    EXPECT_EQ(km_refused.error().message,
              "km.gltf: the scene is 0.0005592 m across, less than 0.01 m, too small to bake (the "
              "tracer's offsets and the bake's distances are lengths in metres): if the file is "
              "in kilometres, --scale 1000 makes it 0.5592 m");
}

TEST(UnitScale, AnImplausibleSizeWarnsAndNamesTheScales) {
    const auto dir = test::tempDir("unit_scale_warn");
    ASSERT_TRUE(writeGeneratedScene("cornell", dir / "box.gltf").ok());
    LoadOptions as_mm; // the 0.56 m box read as if its file were in millimetres x 1000
    as_mm.scale = 1000.0f;
    Result<Scene> huge = loadGltf(dir / "box.gltf", as_mm);
    ASSERT_TRUE(huge.ok());
    ASSERT_FALSE(huge.value().warnings.empty());
    const std::string& w = huge.value().warnings.back();
    EXPECT_NE(w.find("559.2 m across"), std::string::npos) << w;
    // Not a level: its floor, blocks and light give no one storey height, so the warning
    // names every scale with the storeys each would make.
    EXPECT_NE(w.find("storeys are "), std::string::npos) << w;
    EXPECT_NE(w.find("in centimetres, --scale 0.01 makes it 5.592 m"), std::string::npos) << w;
    EXPECT_NE(w.find("in inches, --scale 0.0254 makes it 14.2 m"), std::string::npos) << w;
    EXPECT_NE(w.find("in millimetres, --scale 0.001 makes it 0.5592 m"), std::string::npos) << w;
    const Scene metres = test::loadOrFail(dir / "box.gltf");
    EXPECT_TRUE(implausibleSizeWarning(metres, "box.gltf").empty());
}

// A level 120 m x 40 m in metres: 12 x 4 rooms of 10 m x 3 m x 10 m, a 20 m tower and a flight
// of ten 0.2 m steps.
Scene levelInMetres() {
    Scene s;
    for (int i = 0; i < 12; ++i) {
        for (int j = 0; j < 4; ++j) {
            addBox(s, glm::vec3(10.0f * i, 0.0f, 10.0f * j),
                   glm::vec3(10.0f * i + 10.0f, 3.0f, 10.0f * j + 10.0f));
        }
    }
    addBox(s, glm::vec3(50.0f, 3.0f, 15.0f), glm::vec3(52.0f, 23.0f, 17.0f));
    for (int k = 0; k < 10; ++k) {
        addBox(s, glm::vec3(0.3f * k, 0.2f * k, 41.0f),
               glm::vec3(0.3f * k + 0.3f, 0.2f * k + 0.2f, 43.0f));
    }
    return s;
}

// The storey rule: a 120 m level of 3 m rooms is plausible in metres; the same level in inches
// or centimetres is not, and the warning names first the scale that makes its rooms 3 m high.
TEST(UnitScale, ALevelIsJudgedByItsStoreyHeightNotItsExtent) {
    const Scene metres = levelInMetres();
    EXPECT_FLOAT_EQ(metres.bounds.size().x, 120.0f);
    EXPECT_TRUE(implausibleSizeWarning(metres, "level.gltf").empty())
        << implausibleSizeWarning(metres, "level.gltf");

    Scene inches = levelInMetres();
    applyUnitScale(inches, 1.0f / 0.0254f); // the file as an editor in inches writes it
    const std::string wi = implausibleSizeWarning(inches, "level.gltf");
    EXPECT_NE(wi.find("4724 m across"), std::string::npos) << wi;
    EXPECT_NE(wi.find("storeys are 118 m high"), std::string::npos) << wi;
    // Inches first (3 m storeys), then centimetres (1.18 m) and millimetres (0.118 m).
    EXPECT_NE(wi.find("if the file is in inches, --scale 0.0254 makes it 120 m with 3 m storeys; "
                      "in centimetres"),
              std::string::npos)
        << wi;

    Scene cm = levelInMetres();
    applyUnitScale(cm, 100.0f);
    const std::string wc = implausibleSizeWarning(cm, "level.gltf");
    EXPECT_NE(wc.find("if the file is in centimetres, --scale 0.01 makes it 120 m with 3 m "
                      "storeys; in inches"),
              std::string::npos)
        << wc;
}

// One room exported in centimetres, 500 units high: warned, centimetres first (5 m storeys).
// A scene with no ceiling at all over 100 m is warned with every scale, as before.
TEST(UnitScale, ARoomInCentimetresAndAnOpenSceneStillWarn) {
    Scene room;
    addBox(room, glm::vec3(0.0f), glm::vec3(800.0f, 500.0f, 600.0f));
    const std::string w = implausibleSizeWarning(room, "room.gltf");
    EXPECT_NE(w.find("if the file is in centimetres, --scale 0.01 makes it 8 m with 5 m storeys"),
              std::string::npos)
        << w;

    Scene ground;
    ground.positions = {{0, 0, 0}, {500, 0, 0}, {0, 0, 500}};
    ground.triangles = {{0, 2, 1}};
    ground.materials.resize(1);
    ground.bounds = {glm::vec3(0.0f), glm::vec3(500.0f, 0.0f, 500.0f)};
    const std::string g = implausibleSizeWarning(ground, "ground.gltf");
    EXPECT_NE(g.find("too few of its floors have a ceiling"), std::string::npos) << g;
    EXPECT_NE(g.find("--scale 0.01 makes it 5 m"), std::string::npos) << g;
    EXPECT_NE(g.find("--scale 0.0254 makes it 12.7 m"), std::string::npos) << g;
    EXPECT_NE(g.find("--scale 0.001 makes it 0.5 m"), std::string::npos) << g;
}

TEST(UnitScale, BakeRefusesAConfigScaleTheSceneWasNotLoadedWith) {
    const Scene scene = closedCube(0.0f, 1.0f);
    BakeConfig c;
    c.scale = 0.01f;
    Result<BakeResult> r = bake(scene, c);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("scale: the config says 0.01"), std::string::npos)
        << r.error().message;
}

// An automatic resolution beyond max_probes or max_resolution is cut with a note that says what
// was asked and what is used.
TEST(ResolutionCap, TheNoteSaysWhatWasAskedAndWhatIsUsed) {
    const Scene cube = closedCube(0.0f, 10.0f);
    BakeConfig c;
    c.volumes.push_back(VolumeConfig{});
    c.volumes[0].bounds.padding = 0.0f;
    c.volumes[0].density = 100.0f;             // 1000 probes per axis asked: 1024 after rounding
    c.volumes[0].layout = VolumeLayout::Dense; // the caps of a dense grid
    Result<VolumePlan> plan = planVolumes(cube, c);
    ASSERT_TRUE(plan.ok()) << plan.error().message;
    EXPECT_EQ(plan.value().volumes[0].grid.resolution(), glm::uvec3(32));
    // Two cuts, each said: max_resolution to 256 per axis, then the budget to 32 per axis.
    ASSERT_EQ(plan.value().notes.size(), 2u);
    EXPECT_NE(plan.value().notes[0].find("asks 1024 x 1024 x 1024 probes; max_resolution 256 "
                                         "(--max-resolution) gives 256 x 256 x 256"),
              std::string::npos)
        << plan.value().notes[0];
    const std::string& n = plan.value().notes[1];
    EXPECT_NE(n.find("100 probes/m over 10 x 10 x 10 m asks 1024 x 1024 x 1024 probes"),
              std::string::npos)
        << n;
    EXPECT_NE(n.find("the budget of 32768 probes (max_probes, --max-probes) gives 32 x 32 x 32 "
                     "(probe spacing 0.312"),
              std::string::npos)
        << n;
    // max_resolution below the budget's answer: its own note.
    c.volumes[0].maxResolution = 16;
    Result<VolumePlan> capped = planVolumes(cube, c);
    ASSERT_TRUE(capped.ok());
    EXPECT_EQ(capped.value().volumes[0].grid.resolution(), glm::uvec3(16));
    ASSERT_EQ(capped.value().notes.size(), 1u);
    EXPECT_NE(capped.value().notes[0].find("max_resolution 16 (--max-resolution) gives 16 x 16"),
              std::string::npos)
        << capped.value().notes[0];
    // Within both caps: no note.
    c.volumes[0].maxResolution = 256;
    c.volumes[0].density = 3.0f;
    Result<VolumePlan> fine = planVolumes(cube, c);
    ASSERT_TRUE(fine.ok());
    EXPECT_TRUE(fine.value().notes.empty());
}

} // namespace
