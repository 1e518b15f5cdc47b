// What the CLI prints of text it does not control (terminal_text.hpp), the points CSV parser
// (points_csv.hpp) and `info`'s formatting (info_format.hpp): the code the fuzz targets drive.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "info_format.hpp"
#include "points_csv.hpp"
#include "probekit/formats/json_nesting.hpp"
#include "probekit/formats/pvol.hpp"
#include "terminal_text.hpp"

namespace probekit::cli {
namespace {

// True when `text` holds a byte a terminal acts on: C0, DEL, or the first byte of a C1 control.
bool hasControlBytes(std::string_view text) {
    for (size_t i = 0; i < text.size(); ++i) {
        const auto byte = uint8_t(text[i]);
        if (byte < 0x20 && byte != '\n') {
            return true;
        }
        if (byte == 0x7f || (byte == 0xc2 && i + 1 < text.size() && uint8_t(text[i + 1]) >= 0x80 &&
                             uint8_t(text[i + 1]) <= 0x9f)) {
            return true;
        }
    }
    return false;
}

TEST(TerminalText, EscapesControlsAndInvalidUtf8AndKeepsTheRest) {
    EXPECT_EQ(terminalText("plain ASCII, 42 m^2 (ok)"), "plain ASCII, 42 m^2 (ok)");
    // OSC 0 (window title) ended by BEL, then "clear screen".
    EXPECT_EQ(terminalText("\x1b]0;pwned\x07\x1b[2J"), "\\x1b]0;pwned\\x07\\x1b[2J");
    EXPECT_EQ(terminalText(std::string("a\0b\tc\nd\re\x7f", 10)), "a\\x00b\\x09c\\x0ad\\x0de\\x7f");
    // C1 controls in their UTF-8 form: both bytes; the next code point (U+00A0) is kept.
    EXPECT_EQ(terminalText("\xc2\x80\xc2\x9b\xc2\x9f\xc2\xa0"),
              "\\xc2\\x80\\xc2\\x9b\\xc2\\x9f\xc2\xa0");
    // Well-formed UTF-8 of every length is kept.
    EXPECT_EQ(terminalText("K\xc3\xbc"
                           "che \xe2\x82\xac \xf0\x9f\x8c\x9e"),
              "K\xc3\xbc"
              "che \xe2\x82\xac \xf0\x9f\x8c\x9e");
    // Not UTF-8: stray bytes, overlong forms, surrogates, values past U+10FFFF, cut sequences.
    EXPECT_EQ(terminalText("\xff\xfe"), "\\xff\\xfe");
    EXPECT_EQ(terminalText("\xc0\xaf"), "\\xc0\\xaf");
    EXPECT_EQ(terminalText("\xe0\x80\xaf"), "\\xe0\\x80\\xaf");
    EXPECT_EQ(terminalText("\xed\xa0\x80"), "\\xed\\xa0\\x80");
    EXPECT_EQ(terminalText("\xf4\x90\x80\x80"), "\\xf4\\x90\\x80\\x80");
    EXPECT_EQ(terminalText("ab\xe2\x82"), "ab\\xe2\\x82");
    EXPECT_EQ(terminalText("\x80x"), "\\x80x");
}

TEST(TerminalText, JsonStaysValidAndPrintsNoControlOrInvalidBytes) {
    const nlohmann::json j = {{"name", "\x1b]0;t\x07\x7f\xc2\x9b\xff!"}};
    // nlohmann's own dump refuses the 0xff (type_error 316); jsonText replaces it.
    EXPECT_THROW((void)j.dump(), nlohmann::json::type_error);
    const std::string text = jsonText(j);
    EXPECT_EQ(text, "{\"name\":\"\\u001b]0;t\\u0007\\u007f\\u009b\xef\xbf\xbd!\"}");
    EXPECT_FALSE(hasControlBytes(text));
    const nlohmann::json back = nlohmann::json::parse(text);
    EXPECT_EQ(back["name"], "\x1b]0;t\x07\x7f\xc2\x9b\xef\xbf\xbd!");
}

TEST(PointsCsv, ParsesAndNormalises) {
    const auto points = parsePointsCsv(
        "\xEF\xBB\xBFx,y,z,nx,ny,nz\r\n 1, 2 ,+3,0,0,2\r\n\n-1.5,0,0,0,-1,0", "p.csv");
    ASSERT_TRUE(points.ok()) << points.error().message;
    ASSERT_EQ(points.value().size(), 2u);
    EXPECT_EQ(points.value()[0].position, glm::vec3(1, 2, 3));
    EXPECT_EQ(points.value()[0].normal, glm::vec3(0, 0, 1));
    EXPECT_EQ(points.value()[1].normal, glm::vec3(0, -1, 0));
}

TEST(PointsCsv, ErrorsNameTheLineAndQuoteAtMost80Bytes) {
    EXPECT_EQ(parsePointsCsv("", "p.csv").error().message,
              "p.csv: empty; expected the header \"x,y,z,nx,ny,nz\"");
    EXPECT_EQ(parsePointsCsv("x,y,z\n", "p.csv").error().message,
              "p.csv:1: expected the header \"x,y,z,nx,ny,nz\", found \"x,y,z\"");
    EXPECT_EQ(parsePointsCsv("x,y,z,nx,ny,nz\n1,2,3\n", "p.csv").error().message,
              "p.csv:2: expected 6 fields (x,y,z,nx,ny,nz), found 3");
    EXPECT_EQ(parsePointsCsv("x,y,z,nx,ny,nz\n1,2,3,0,0,0\n", "p.csv").error().message,
              "p.csv:2: the normal (0, 0, 0) has no direction (zero length)");
    EXPECT_EQ(parsePointsCsv("x,y,z,nx,ny,nz\n1,nan,3,0,1,0\n", "p.csv").error().message,
              "p.csv:2: column 2 (y): \"nan\" is not a finite number");
    const std::string long_field(1000, '7');
    EXPECT_EQ(
        parsePointsCsv("x,y,z,nx,ny,nz\n1,2," + long_field + "x,0,1,0\n", "p.csv").error().message,
        "p.csv:2: column 3 (z): \"" + std::string(80, '7') +
            "\"... (1001 bytes) is not a finite number");
    // A million commas: counted, not kept.
    EXPECT_EQ(
        parsePointsCsv("x,y,z,nx,ny,nz\n" + std::string(1'000'000, ','), "p.csv").error().message,
        "p.csv:2: expected 6 fields (x,y,z,nx,ny,nz), found 1000001");
}

TEST(PointsCsv, PointCountIsBounded) {
    const std::string text = "x,y,z,nx,ny,nz\n0,0,0,0,1,0\n0,0,0,0,1,0\n0,0,0,0,1,0\n";
    EXPECT_TRUE(parsePointsCsv(text, "p.csv", 3).ok());
    EXPECT_EQ(parsePointsCsv(text, "p.csv", 2).error().message,
              "p.csv:4: more than 2 points, the most one file may hold");
}

std::vector<uint8_t> readHostile(const char* name) {
    std::ifstream in(std::filesystem::path(PROBEKIT_TEST_DATA_DIR) / "hostile" / name,
                     std::ios::binary);
    return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

TEST(InfoFormat, EscapesNamesAndMetadataThatAreNotSafeToPrint) {
    // tests/data/hostile/escapes.pvol (its recipe is in test_pvol.cpp): terminal escapes and
    // bytes that are not UTF-8 in the volume name, tool version, method and parameters.
    const std::vector<uint8_t> bytes = readHostile("escapes.pvol");
    const Result<PvolFile> file = decodePvol(bytes, "escapes.pvol");
    ASSERT_TRUE(file.ok()) << file.error().message;

    const Result<std::string> text = formatInfo(file.value(), "escapes.pvol", bytes.size(), false);
    ASSERT_TRUE(text.ok()) << text.error().message;
    EXPECT_FALSE(hasControlBytes(text.value())) << text.value();
    EXPECT_NE(text.value().find("  volume '\\x1b]0;pwned\\x07\\x1b[2J\\xc2\\x9b\\xff': 2x2x2 "
                                "center probes, L1, float, 384 texel bytes\n"),
              std::string::npos)
        << text.value();
    EXPECT_NE(text.value().find("baked by probekit \\x1b[31mred\\x1b[0m, method path\\x7f,"),
              std::string::npos)
        << text.value();
    EXPECT_NE(text.value().find("  parameters: {\"note\": \"\\xff\\xfe\\x1b[5m\"}\n"),
              std::string::npos)
        << text.value();

    const Result<std::string> json = formatInfo(file.value(), "escapes.pvol", bytes.size(), true);
    ASSERT_TRUE(json.ok()) << json.error().message;
    EXPECT_FALSE(hasControlBytes(json.value())) << json.value();
    const nlohmann::json parsed = nlohmann::json::parse(json.value());
    EXPECT_EQ(parsed["volumes"][0]["name"], "\x1b]0;pwned\x07\x1b[2J\xc2\x9b\xef\xbf\xbd");
    EXPECT_EQ(parsed["metadata"]["parameters"], "{\"note\": \"\xef\xbf\xbd\xef\xbf\xbd\x1b[5m\"}");
    EXPECT_EQ(parsed["file_bytes"], bytes.size());
}

// Issue 31: the reader refuses tests/data/hostile/deep-parameters.pvol (parameters nested
// 100000 levels deep) naming the file and the field; a file built in code with such parameters
// is shown with them as a string (no recursion over them, output linear in their size) instead
// of overflowing the stack or printing indent x depth spaces per line.
TEST(InfoFormat, DeeplyNestedParametersAreRefusedOrShownAsText) {
    const std::vector<uint8_t> bytes = readHostile("deep-parameters.pvol");
    const Result<PvolFile> refused = decodePvol(bytes, "deep-parameters.pvol");
    ASSERT_FALSE(refused.ok());
    EXPECT_EQ(refused.error().message,
              "deep-parameters.pvol: metadata.parameters_json: JSON arrays and objects nest "
              "100000 levels deep (level 65 opens at byte 64), more than the limit of 64");

    PvolFile file;
    file.metadata.parametersJson.assign(100000, '[');
    file.metadata.parametersJson.append(100000, ']');
    const Result<std::string> json = formatInfo(file, "built.pvol", 0, true);
    ASSERT_TRUE(json.ok()) << json.error().message;
    EXPECT_LT(json.value().size(), 300000u); // the 200,000 bytes as one string, plus the rest
    const nlohmann::json parsed = nlohmann::json::parse(json.value());
    EXPECT_EQ(parsed["metadata"]["parameters"], file.metadata.parametersJson);
}

// The one parse of untrusted JSON text: nesting up to kMaxJsonDepth (64) parses, deeper is
// refused before parsing, and each error names its source.
TEST(JsonText, NestingIsLimitedAndErrorsNameTheSource) {
    std::string at_limit(64, '[');
    at_limit.append(64, ']');
    const Result<nlohmann::json> ok = parseJsonText<nlohmann::json>(at_limit, "cfg.json");
    ASSERT_TRUE(ok.ok()) << ok.error().message;
    EXPECT_TRUE(ok.value().is_array());

    std::string deeper = "{\"a\": ";
    deeper.append(64, '{');
    const Result<nlohmann::json> deep = parseJsonText<nlohmann::json>(deeper, "cfg.json");
    ASSERT_FALSE(deep.ok());
    EXPECT_EQ(deep.error().code, ErrorCode::OutOfRange);
    EXPECT_EQ(deep.error().message,
              "cfg.json: JSON arrays and objects nest 65 levels deep (level 65 opens at byte 69), "
              "more than the limit of 64");

    const Result<nlohmann::json> bad = parseJsonText<nlohmann::json>("{\"a\": }", "cfg.json");
    ASSERT_FALSE(bad.ok());
    EXPECT_EQ(bad.error().code, ErrorCode::InvalidArgument);
    EXPECT_TRUE(bad.error().message.starts_with("cfg.json: not valid JSON: "))
        << bad.error().message;
}

// A key given twice in one object is refused with its path, at any depth and inside arrays;
// the same key in two different objects is not a repeat.
TEST(JsonText, AKeyGivenTwiceIsRefusedWithItsPath) {
    const Result<nlohmann::json> top =
        parseJsonText<nlohmann::json>("{\"seed\": 1, \"seed\": 2}", "cfg.json");
    ASSERT_FALSE(top.ok());
    EXPECT_EQ(top.error().code, ErrorCode::InvalidArgument);
    EXPECT_EQ(top.error().message, "cfg.json: seed: given twice");

    const std::string nested = R"({"volumes": [{"name": "a", "bounds": {"min": [0, 0, 0]}},
        {"name": "b", "bounds": {"min": [1, 1, 1], "max": [2, 2, 2], "min": [0, 0, 0]}}]})";
    const Result<nlohmann::json> deep = parseJsonText<nlohmann::json>(nested, "cfg.json");
    ASSERT_FALSE(deep.ok());
    EXPECT_EQ(deep.error().message, "cfg.json: volumes[1].bounds.min: given twice");

    const std::string distinct = R"({"a": {"x": 1}, "b": {"x": 2}, "c": [{"x": 3}, {"x": 4}]})";
    const Result<nlohmann::json> ok = parseJsonText<nlohmann::json>(distinct, "cfg.json");
    ASSERT_TRUE(ok.ok()) << ok.error().message;
    EXPECT_EQ(ok.value()["c"][1]["x"], 4);
    EXPECT_EQ(ok.value()["b"]["x"], 2);
}

TEST(InfoFormat, AnInvalidVolumeGivesAnErrorNotACrash) {
    PvolFile file;
    file.volumes.emplace_back(); // no texels, validity or grid to speak of
    file.volumes.back().desc.layout = VolumeLayout::Bricked;
    file.volumes.back().desc.bricks.maxLevel = 0;
    file.volumes.back().desc.bricks.bricks.push_back({glm::uvec3(0), 3}); // level above max
    const Result<std::string> text = formatInfo(file, "made.pvol", 0, false);
    ASSERT_FALSE(text.ok());
    EXPECT_TRUE(text.error().message.starts_with("made.pvol: volume 0: volume '': "))
        << text.error().message;
}

} // namespace
} // namespace probekit::cli
