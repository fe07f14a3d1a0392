// PROTOCOL.md's sample session is what the code does: every client line parses (or fails with
// exactly the error on the next line) and every server line is what serialize() prints.
#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

#include "proto/messages.hpp"

namespace grotto::proto {
namespace {

std::vector<std::string> session_lines() {
  std::ifstream in(GROTTO_PROTOCOL_MD);
  EXPECT_TRUE(in.good()) << GROTTO_PROTOCOL_MD;
  std::vector<std::string> lines;
  bool in_session = false;
  for (std::string line; std::getline(in, line);) {
    if (line.starts_with("## ")) in_session = line == "## Sample session";
    if (in_session && (line.starts_with("→ {") || line.starts_with("← {"))) {
      lines.push_back(line);
    }
  }
  return lines;
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
