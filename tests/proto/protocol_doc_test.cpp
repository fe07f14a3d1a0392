// PROTOCOL.md's sample session is what the code does: every client line parses (or fails with
// exactly the error on the next line) and every server line is what serialize() prints.
#include <gtest/gtest.h>

#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "proto/lod.hpp"
#include "proto/messages.hpp"

namespace grotto::proto {
namespace {

// The lines of one "## " section of PROTOCOL.md that start with one of `prefixes`.
std::vector<std::string> section_lines(std::string_view section,
                                       std::initializer_list<std::string_view> prefixes) {
  std::ifstream in(GROTTO_PROTOCOL_MD);
  EXPECT_TRUE(in.good()) << GROTTO_PROTOCOL_MD;
  std::vector<std::string> lines;
  bool inside = false;
  for (std::string line; std::getline(in, line);) {
    if (line.starts_with("## ")) inside = line.substr(3) == section;
    for (std::string_view p : prefixes) {
      if (inside && line.starts_with(p)) lines.push_back(line);
    }
  }
  return lines;
}

std::vector<std::string> session_lines() {
  return section_lines("Sample session", {"→ {", "← {"});
}

TEST(ProtocolDoc, error_code_table_lists_every_wire_code_with_its_fatality) {
  std::vector<std::string> rows = section_lines("Error codes", {"| `"});
  std::set<std::string> documented;
  for (const std::string& row : rows) {
    std::size_t end = row.find('`', 3);
    ASSERT_NE(end, std::string::npos) << row;
    std::string name = row.substr(3, end - 3);
    documented.insert(name);
    std::optional<ErrorCode> code = parse_wire_code(name);
    ASSERT_TRUE(code.has_value()) << "PROTOCOL.md documents an unknown code " << name;
    std::string fatal = row.substr(row.find("| ", end) + 2, 3);
    EXPECT_EQ(fatal == "yes", is_fatal(*code)) << name << ": table says " << fatal;
  }
  for (int c = 0; c <= static_cast<int>(ErrorCode::kTimeout); ++c) {
    std::string name = wire_code_name(static_cast<ErrorCode>(c));
    EXPECT_TRUE(documented.count(name)) << name << " is not in PROTOCOL.md's error table";
  }
}

TEST(ProtocolDoc, levels_of_detail_table_is_proto_lod_mapping) {
  std::vector<std::string> rows = section_lines("Levels of detail", {"| 0", "| 1", "| 2", "| 3"});
  ASSERT_EQ(rows.size(), std::size_t{kMaxWireLod} + 1);
  for (const std::string& row : rows) {
    SCOPED_TRACE(row);
    uint32_t wire = static_cast<uint32_t>(std::stoul(row.substr(2)));
    std::optional<mesh::Lod> lod = mesh_lod(wire);
    ASSERT_TRUE(lod.has_value());
    // The second column names mesh::Lod by lod_name(): "| 0 | `patch` | ...".
    EXPECT_NE(row.find(std::string("| `") + mesh::lod_name(*lod) + "` |"), std::string::npos);
  }
}

TEST(ProtocolDoc, sample_session_matches_the_implementation) {
  std::vector<std::string> lines = session_lines();
  ASSERT_GE(lines.size(), 10u);
  const std::string to_server = "→ ", to_client = "← ";
  for (std::size_t i = 0; i < lines.size(); ++i) {
    SCOPED_TRACE(lines[i]);
    if (lines[i].starts_with(to_server)) {
      std::string text = lines[i].substr(to_server.size());
      Ref ref;
      Result<ClientMessage> m = parse_client_message(text, Limits{}, &ref);
      if (m.ok()) {
        EXPECT_EQ(serialize(*m), text);
        continue;
      }
      // A refused message: the next line is the server's error, word for word.
      ASSERT_LT(i + 1, lines.size());
      ASSERT_TRUE(lines[i + 1].starts_with(to_client));
      EXPECT_EQ(serialize(ServerMessage(error_reply(m.error(), ref))),
                lines[i + 1].substr(to_client.size()));
    } else {
      std::string text = lines[i].substr(to_client.size());
      Result<ServerMessage> m = parse_server_message(text, Limits{});
      ASSERT_TRUE(m.ok()) << m.error().message;
      EXPECT_EQ(serialize(*m), text);
    }
  }
}

}  // namespace
}  // namespace grotto::proto
