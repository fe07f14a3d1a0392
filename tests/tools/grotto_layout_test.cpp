// grotto-layout as a user runs it: a real process, real files, real exit codes.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "common/png/png.hpp"
#include "tests/tools/layout_process.hpp"

namespace {

using grotto::testing::ProcessResult;

ProcessResult run(const std::string& args, const char* device = "auto") {
  return grotto::testing::run_layout(args, device);
}

std::string read(const std::filesystem::path& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

TEST(GrottoLayout, help_documents_the_options) {
  ProcessResult r = run("--help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* flag :
       {"--seed", "--svg", "--json", "--obj", "--glb", "--room", "--tunnel-chance", "--bias"}) {
    EXPECT_NE(r.output.find(flag), std::string::npos) << flag;
  }
}

TEST(GrottoLayout, writes_a_picture_and_json) {
  auto dir =
      std::filesystem::temp_directory_path() / ("grotto-layout-test-" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  ProcessResult r = run("--seed 3 --sectors 1 --svg '" + (dir / "c.svg").string() + "' --json '" +
                        (dir / "c.json").string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::string svg = read(dir / "c.svg");
  EXPECT_EQ(svg.rfind("<svg", 0), 0u);
  EXPECT_NE(svg.find("<circle"), std::string::npos);
  EXPECT_NE(svg.find("</svg>"), std::string::npos);
  std::string json = read(dir / "c.json");
  EXPECT_NE(json.find("\"rooms\""), std::string::npos);
  EXPECT_NE(json.find("\"portals\""), std::string::npos);
  EXPECT_NE(json.find("\"spawn\""), std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST(GrottoLayout, exports_room_meshes_as_obj_on_either_compute_path) {
  auto dir =
      std::filesystem::temp_directory_path() / ("grotto-obj-test-" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  for (const char* device : {"auto", "none"}) {
    std::string obj = (dir / (std::string(device) + ".obj")).string();
    ProcessResult r = run(std::string("--seed 3 --sectors 1 --obj '") + obj + "'", device);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    std::ifstream f(obj);
    std::string line;
    size_t objects = 0, vertices = 0, faces = 0;
    while (std::getline(f, line)) {
      objects += line.rfind("o room_", 0) == 0;
      vertices += line.rfind("v ", 0) == 0;
      faces += line.rfind("f ", 0) == 0;
    }
    EXPECT_GT(objects, 50u) << device;
    EXPECT_GT(vertices, 20000u) << device;
    EXPECT_GT(faces, vertices) << device;
    EXPECT_NE(r.output.find(std::string("compute_path=\"") +
                            (device == std::string("none") ? "cpu" : "opencl")),
              std::string::npos)
        << r.output;
  }
  std::filesystem::remove_all(dir);
}

TEST(GrottoLayout, renders_a_lit_picture_without_a_gpu) {
  auto path = std::filesystem::temp_directory_path() /
              ("grotto-png-test-" + std::to_string(getpid()) + ".png");
  ProcessResult r = run("--seed 3 --sectors 1 --png '" + path.string() + "'", "none");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto image = grotto::png::read_png(path.string());
  std::filesystem::remove(path);
  ASSERT_TRUE(image.ok()) << image.error().message;
  const size_t w = 1200, h = 800;
  ASSERT_EQ(image.value().width, static_cast<int>(w));
  ASSERT_EQ(image.value().height, static_cast<int>(h));
  const std::vector<unsigned char>& rgb = image.value().rgb;
  size_t lit = 0;
  for (size_t i = 0; i + 2 < rgb.size(); i += 3)
    lit += rgb[i] > 40 || rgb[i + 1] > 40 || rgb[i + 2] > 40;  // brighter than the background
  EXPECT_GT(lit, w * h / 20) << "the cave covers part of the picture";
  EXPECT_LT(lit, w * h * 9 / 10) << "and leaves background around it";
}

TEST(GrottoLayout, prints_one_room) {
  ProcessResult r = run("--seed 3 --room 0.0.0.x0");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("\"id\": \"0.0.0.x0\""), std::string::npos) << r.output;
}

// What the world's rock made of a room: its portals' sections and the geology at its centre, as
// engines read them (the glb's room extras carry the same).
TEST(GrottoLayout, a_room_says_its_portals_sections_and_its_rock) {
  ProcessResult r = run("--seed 7 --room 0.0.0.r0");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto j = nlohmann::json::parse(r.output.substr(r.output.find('{')), nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << r.output;
  ASSERT_FALSE(j["portals"].empty());
  for (const auto& p : j["portals"]) {
    const std::string kind = p["section"]["kind"].get<std::string>();
    EXPECT_TRUE(kind == "tube" || kind == "lens" || kind == "canyon" || kind == "keyhole" ||
                kind == "fissure")
        << kind;
    EXPECT_GT(p["section"]["half_width"].get<double>(), 0);
    EXPECT_GT(p["section"]["half_height"].get<double>(), 0);
  }
  const auto& g = j["geology"];
  EXPECT_GE(g["bed_thickness"].get<double>(), 0.3);
  EXPECT_GE(g["joints"].size(), 2u);
  EXPECT_TRUE(g["phreatic"].is_boolean());
}

TEST(GrottoLayout, bad_input_gets_a_clear_error) {
  struct Case {
    const char* args;
    const char* says;
  } cases[] = {
      {"--room 1.2.banana", "malformed room id"},
      {"--room 0.0.0.r4000", "does not exist"},
      {"--from 1,2", "--from must be three integers"},
      {"--from 0,0,0 --to -1,0,0", "--to must not be below --from"},
      {"--from 99999,0,0", "outside the sector range"},
      {"--tunnel-chance 2", "tunnel_chance must be in [0, 1]"},
      {"--bias 0,0,0", "bias must have"},
      {"--sector-size 10", "sector_size"},
      {"--sectors 9", "--sectors"},
      {"--character lava", "--character"},
      {"--seed -5", "--seed"},
      {"--lod medium --obj x.obj", "--lod"},
      {"--from 0,0,0 --to 9,9,9", "at most 512"},
  };
  for (const Case& c : cases) {
    ProcessResult r = run(c.args);
    EXPECT_NE(r.exit_code, 0) << c.args;
    EXPECT_NE(r.output.find(c.says), std::string::npos) << c.args << " said: " << r.output;
  }
}

// The command-line conventions every Grotto binary keeps: a flag it does not know or a value
// its check refuses exits 2; the world is seed 7 unless told otherwise.
TEST(GrottoLayout, a_bad_flag_exits_2_and_the_default_world_is_seed_7) {
  for (const char* args : {"--no-such-flag", "--sectors 9", "--character lava", "--seed", "--glb",
                           "--lod x --glb y"}) {
    ProcessResult r = run(args);
    EXPECT_EQ(r.exit_code, 2) << args << " said: " << r.output;
  }
  EXPECT_EQ(run("--help").exit_code, 0);
  ProcessResult plain = run("--room 0.0.0.r0");
  ProcessResult seven = run("--seed 7 --room 0.0.0.r0");
  ASSERT_EQ(plain.exit_code, 0) << plain.output;
  EXPECT_EQ(plain.output, seven.output);
  EXPECT_NE(plain.output, run("--seed 1 --room 0.0.0.r0").output);
  EXPECT_NE(run("--help").output.find("--seed TEXT=7 "), std::string::npos) << run("--help").output;
}

}  // namespace
