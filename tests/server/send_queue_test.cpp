// A session's send queue (server/send_queue.hpp) by tables: the room frame due soonest goes next,
// past prefetch frames already queued, but never past a control message or the frame being
// written. Each ordered row is also run unordered (first in, first out, as sessions once did)
// and must come out differently there, so every row can fail.
#include "server/send_queue.hpp"

#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

namespace grotto::server {
namespace {

// A room frame named `name` (its bytes), due at `due` ms.
Outgoing room(const std::string& name, uint64_t due) {
  auto r = std::make_shared<EncodedRoom>();
  r->frame.assign(name.begin(), name.end());
  return Outgoing{{}, std::move(r), due};
}
Outgoing text(const std::string& t) {
  return Outgoing{t, nullptr, 0};
}

// The names in the order they go out; "writing" marks pushes made while the front is written.
std::vector<std::string> drain(SendQueue& q) {
  std::vector<std::string> out;
  while (!q.empty()) {
    const Outgoing& f = q.front();
    out.push_back(f.room ? std::string(f.room->frame.begin(), f.room->frame.end()) : f.text);
    q.start_write();
    q.pop_front();
  }
  return out;
}

struct Step {
  Outgoing out;
  bool start_write_before = false;  // the front's write starts before this push
};

struct Row {
  const char* name;
  std::vector<Step> steps;
  std::vector<std::string> ordered;    // what goes out, in order
  std::vector<std::string> unordered;  // the same, first in first out
};

TEST(SendQueue, urgent_rooms_overtake_queued_prefetch_table) {
  const std::vector<Row> rows = {
      {"an urgent room goes before the prefetch queued ahead of it",
       {{room("far1", 4000)}, {room("far2", 3500)}, {room("near", 300)}},
       {"near", "far2", "far1"},
       {"far1", "far2", "near"}},
      {"the frame being written stays first",
       {{room("far1", 4000)}, {room("far2", 3500), true}, {room("near", 300)}},
       {"far1", "near", "far2"},
       {"far1", "far2", "near"}},
      {"a control message keeps its place: nothing overtakes it",
       {{room("far1", 4000)}, {text("pong")}, {room("far2", 3500)}, {room("near", 300)}},
       {"far1", "pong", "near", "far2"},
       {"far1", "pong", "far2", "near"}},
      {"equal due: arrival order",
       {{room("a", 1000)}, {room("b", 1000)}, {room("c", 500)}, {room("d", 1000)}},
       {"c", "a", "b", "d"},
       {"a", "b", "c", "d"}},
  };
  for (const Row& row : rows) {
    SCOPED_TRACE(row.name);
    for (bool ordered : {true, false}) {
      SendQueue q(ordered);
      size_t bytes = 0;
      for (const Step& s : row.steps) {
        if (s.start_write_before) q.start_write();
        bytes += s.out.size();
        q.push(s.out);
      }
      EXPECT_EQ(q.bytes(), bytes);
      EXPECT_EQ(drain(q), ordered ? row.ordered : row.unordered) << "ordered " << ordered;
      EXPECT_EQ(q.bytes(), 0u);
    }
    EXPECT_NE(row.ordered, row.unordered) << "a row that cannot fail";
  }
}

TEST(SendQueue, a_slow_clients_queue_keeps_only_the_frame_being_written) {
  SendQueue q;
  q.push(room("a", 10));
  q.start_write();
  q.push(room("b", 5));
  q.push(text("t"));
  q.drop_waiting();
  ASSERT_EQ(q.size(), 1u);
  EXPECT_EQ(q.bytes(), 1u);
  EXPECT_TRUE(q.writing());
  q.pop_front();
  EXPECT_TRUE(q.empty());
  EXPECT_FALSE(q.writing());
}

}  // namespace
}  // namespace grotto::server
