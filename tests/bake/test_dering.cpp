// Deringing in the bake (BakeConfig::dering, baker/src/volume/dering.hpp): every stored probe of
// every method, layout, SH order and storage has E >= 0 for every normal, checked on the
// coefficients as stored (half decoded) with the exact minimum of sh.hpp and a dense set of normals
// in float as the runtime evaluates them; the same bakes with deringing off have negative probes,
// so the check can fail. The scene is the generated Cornell box (its emitter is a small bright
// square under the ceiling) and, for the strongest ringing, the thin-wall rooms' 20 W/sr point
// light.
#include <algorithm>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "bake_test_support.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/formats/pvol.hpp"
#include "probekit/formats/sh.hpp"

namespace probekit::baker {
namespace {

using test::generatedScene;

// Normals per probe for the float check: 4096 Fibonacci points are ~3.5 degrees apart, and the
// exact minimum (sh.hpp) covers what lies between them.
constexpr int kCheckNormals = 4096;

struct ProbeCheck {
    uint64_t probes = 0;
    uint64_t belowMargin = 0;       // some channel's exact minimum < kDeringMargin x its mean
    uint64_t negativeAtNormals = 0; // some channel's float E < 0 at a check normal
    double worstRelative = 0.0;     // smallest exact minimum / mean over channels with mean > 0
};

// Every stored probe (Volume::probe decodes half as stored) of every volume.
ProbeCheck checkStored(const PvolFile& file) {
    ProbeCheck c;
    c.worstRelative = std::numeric_limits<double>::infinity();
    for (const Volume& v : file.volumes) {
        for (size_t i = 0; i < v.probeCount(); ++i) {
            const sh::ShRgb s = v.probe(i);
            ++c.probes;
            bool below = false;
            for (int ch = 0; ch < 3; ++ch) {
                const double mean = sh::meanIrradiance(s, ch);
                const double min_e = sh::minimumIrradiance(s, v.desc.shOrder, ch).value;
                below = below || min_e < sh::kDeringMargin * std::max(mean, 0.0) || mean < 0.0;
                if (mean > 0.0) {
                    c.worstRelative = std::min(c.worstRelative, min_e / mean);
                }
            }
            c.belowMargin += below ? 1 : 0;
            bool negative = false;
            for (int k = 0; k < kCheckNormals && !negative; ++k) {
                const glm::vec3 e =
                    sh::irradiance(s, v.desc.shOrder, sh::fibonacciDirection(k, kCheckNormals));
                negative = e.x < 0.0f || e.y < 0.0f || e.z < 0.0f;
            }
            c.negativeAtNormals += negative ? 1 : 0;
        }
    }
    return c;
}

struct Variant {
    const char* name;
    Method method;
    VolumeLayout layout;
    sh::Order order;
    Storage storage;
};

VolumeConfig cornellVolume(const Variant& v) {
    VolumeConfig vc;
    vc.bounds.mode = BoundsMode::Custom;
    vc.bounds.min = glm::vec3(0.01f);
    vc.bounds.max = glm::vec3(0.546f, 0.538f, 0.549f);
    vc.layout = v.layout;
    vc.shOrder = v.order;
    vc.storage = v.storage;
    if (v.layout == VolumeLayout::Bricked) {
        vc.resolution = glm::uvec3(2);
        vc.maxLevel = 1;
    } else {
        vc.resolution = glm::uvec3(8);
    }
    return vc;
}

BakeConfig cornellConfig(const Variant& v, bool dering) {
    BakeConfig c;
    c.method = v.method;
    c.path.samples = 128;
    c.vpl.count = 4096;
    c.vpl.directSamples = 128;
    c.lpv.vplCount = 4096;
    c.lpv.grid = 16;
    c.dering = dering;
    c.volumes = {cornellVolume(v)};
    return c;
}

TEST(DeringBake, EveryStoredProbeIsNonNegativeForEveryMethodLayoutOrderAndStorage) {
    const Scene scene = generatedScene("cornell");
    const Variant variants[] = {
        {"path dense L2 half", Method::Path, VolumeLayout::Dense, sh::Order::L2, Storage::Float16},
        {"path dense L2 float", Method::Path, VolumeLayout::Dense, sh::Order::L2, Storage::Float32},
        {"path dense L1 half", Method::Path, VolumeLayout::Dense, sh::Order::L1, Storage::Float16},
        {"path dense L1 float", Method::Path, VolumeLayout::Dense, sh::Order::L1, Storage::Float32},
        {"path bricked L2 half", Method::Path, VolumeLayout::Bricked, sh::Order::L2,
         Storage::Float16},
        {"path bricked L1 float", Method::Path, VolumeLayout::Bricked, sh::Order::L1,
         Storage::Float32},
        {"vpl dense L2 half", Method::Vpl, VolumeLayout::Dense, sh::Order::L2, Storage::Float16},
        {"lpv dense L1 half", Method::Lpv, VolumeLayout::Dense, sh::Order::L1, Storage::Float16},
    };
    for (const Variant& v : variants) {
        SCOPED_TRACE(v.name);
        Result<BakeResult> off = bake(scene, cornellConfig(v, false));
        Result<BakeResult> on = bake(scene, cornellConfig(v, true));
        ASSERT_TRUE(off.ok()) << off.error().message;
        ASSERT_TRUE(on.ok()) << on.error().message;
        const ProbeCheck before = checkStored(off.value().file);
        const ProbeCheck after = checkStored(on.value().file);
        const BakeStats& s = on.value().stats;
        std::printf("[dering cornell] %s: without deringing %llu of %llu probes below the margin "
                    "(%llu negative at %d normals, worst min E %.3g of the mean); with: %llu "
                    "deringed, irradiance changed by %.3g RMS on average and %.3g at most, %llu "
                    "below the margin, worst min E %.3g of the mean\n",
                    v.name, (unsigned long long)before.belowMargin,
                    (unsigned long long)before.probes, (unsigned long long)before.negativeAtNormals,
                    kCheckNormals, before.worstRelative, (unsigned long long)s.deringedProbes,
                    s.deringMeanChange, s.deringMaxChange, (unsigned long long)after.belowMargin,
                    after.worstRelative);
        // Off: the test can fail, there are probes to fix.
        EXPECT_GT(before.negativeAtNormals, 0u);
        EXPECT_EQ(off.value().stats.deringedProbes, 0u);
        // On: none left, by the exact minimum and at the normals.
        EXPECT_EQ(after.belowMargin, 0u);
        EXPECT_EQ(after.negativeAtNormals, 0u);
        EXPECT_GT(s.deringedProbes, 0u);
        EXPECT_LE(s.deringMaxChange, 1.0);
        // Bricked: the count is of probes a deringing pass changed; a border probe stitched
        // from deringed probes passes as it is and is not counted (BakeStats::deringedProbes),
        // so it may be below the probes that fail without deringing.
        if (v.layout == VolumeLayout::Dense) {
            // Dense: deringing changes exactly the probes that fail as stored, and leaves every
            // other probe's bytes alone.
            EXPECT_EQ(s.deringedProbes, before.belowMargin);
            const Volume& a = off.value().file.volumes[0];
            const Volume& b = on.value().file.volumes[0];
            ASSERT_EQ(a.probeCount(), b.probeCount());
            uint64_t differ = 0;
            for (size_t i = 0; i < a.probeCount(); ++i) {
                differ += a.probe(i) == b.probe(i) ? 0 : 1;
            }
            EXPECT_EQ(differ, s.deringedProbes);
        }
    }
}

// The thin-wall rooms' point light rings hardest (a probe near it sees almost a delta): the
// largest change a bake makes, and that the bake still stores only non-negative probes.
TEST(DeringBake, PointLightRoomsAreNonNegativeAndTheCostIsBounded) {
    const Scene scene = generatedScene("thin-wall");
    for (const sh::Order order : {sh::Order::L2, sh::Order::L1}) {
        BakeConfig c = test::sceneVolume(64, glm::uvec3(16, 8, 8));
        c.volumes[0].shOrder = order;
        c.dering = false;
        Result<BakeResult> off = bake(scene, c);
        c.dering = true;
        Result<BakeResult> on = bake(scene, c);
        ASSERT_TRUE(off.ok()) << off.error().message;
        ASSERT_TRUE(on.ok()) << on.error().message;
        const ProbeCheck before = checkStored(off.value().file);
        const ProbeCheck after = checkStored(on.value().file);
        const BakeStats& s = on.value().stats;
        std::printf("[dering thin-wall] %s: without deringing %llu of %llu probes below the "
                    "margin (%llu negative at %d normals); with: %llu deringed, change %.3g RMS "
                    "on average, %.3g at most\n",
                    order == sh::Order::L2 ? "L2" : "L1", (unsigned long long)before.belowMargin,
                    (unsigned long long)before.probes, (unsigned long long)before.negativeAtNormals,
                    kCheckNormals, (unsigned long long)s.deringedProbes, s.deringMeanChange,
                    s.deringMaxChange);
        EXPECT_GT(before.negativeAtNormals, 0u);
        EXPECT_EQ(after.belowMargin, 0u);
        EXPECT_EQ(after.negativeAtNormals, 0u);
        // A lone delta costs 0.106 (L2) and 0.378 (L1) of E's RMS (sh.hpp); a probe also sees
        // the rooms' indirect light and its own Monte Carlo noise, which can ask for more: no
        // probe may lose more than half of E's RMS.
        EXPECT_LT(s.deringMaxChange, 0.5);
    }
}

TEST(DeringBake, BitIdenticalForOneAndTwoThreads) {
    const Scene scene = generatedScene("cornell");
    for (const VolumeLayout layout : {VolumeLayout::Dense, VolumeLayout::Bricked}) {
        const Variant v{"", Method::Path, layout, sh::Order::L2, Storage::Float16};
        const BakeConfig c = cornellConfig(v, true);
        auto [a, b] = test::bakeOnOneAndTwoThreads(scene, c);
        ASSERT_TRUE(a.ok() && b.ok());
        EXPECT_GT(a.value().stats.deringedProbes, 0u);
        EXPECT_EQ(a.value().stats.deringedProbes, b.value().stats.deringedProbes);
        EXPECT_EQ(a.value().stats.deringMaxChange, b.value().stats.deringMaxChange);
        EXPECT_EQ(encodePvol(a.value().file), encodePvol(b.value().file));
    }
}

TEST(DeringConfig, ParsesAndRejectsNonBooleans) {
    Result<BakeConfig> off = parseBakeConfig(R"({"dering": false})", "bake.json");
    ASSERT_TRUE(off.ok()) << off.error().message;
    EXPECT_FALSE(off.value().dering);
    Result<BakeConfig> defaults = parseBakeConfig("{}", "bake.json");
    ASSERT_TRUE(defaults.ok());
    EXPECT_TRUE(defaults.value().dering);
    EXPECT_NE(describeConfig(defaults.value()).find("\"dering\":true"), std::string::npos);
    const test::ConfigErrorCase cases[] = {
        {R"({"dering": 1})", "bake.json: dering"},
        {R"({"dering": "yes"})", "bake.json: dering"},
    };
    test::expectConfigErrors(cases);
}

} // namespace
} // namespace probekit::baker
