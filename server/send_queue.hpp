// What a WebSocket session has to send its client, in the order it goes out. Sessions write one
// message at a time (Beast allows one async_write in flight); the rest wait here. A room frame
// waiting here overtakes the room frames due later than it (earliest due first, ties in arrival
// order), so a room the player is about to walk into never waits behind prefetch frames already
// queued for the same connection: urgent rooms go first at every stage. A control message
// (text) keeps its place and nothing overtakes it: replies, errors and pongs stay in order with
// what went before them. The message being written is never moved.
//
// Plain data, no sockets or Asio: tests/server/send_queue_test.cpp drives it by tables.
// Not thread-safe: one session's strand owns it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <string>

#include "server/rooms.hpp"

namespace grotto::server {

struct Outgoing {
  std::string text;     // a control message, or
  RoomPtr room;         // a room frame (shared with the cache, not copied)
  uint64_t due_ms = 0;  // rooms: when the player can reach it (steady ms; request time + priority)
  size_t size() const { return room ? room->frame.size() : text.size(); }
};

class SendQueue {
 public:
  // `ordered` false: first in, first out (what sessions did before; tests show the difference).
  explicit SendQueue(bool ordered = true) : ordered_(ordered) {}

  // Queues a message: a room frame goes before the room frames due later than it that wait
  // behind the last control message (and behind the message being written); a control message
  // goes last.
  void push(Outgoing out);
  bool empty() const { return queue_.empty(); }
  size_t size() const { return queue_.size(); }
  size_t bytes() const { return bytes_; }  // of every message held, the one being written too
  // The next message to write; once writing starts (start_write) it stays at the front until
  // pop_front.
  const Outgoing& front() const { return queue_.front(); }
  void start_write() { writing_ = true; }
  bool writing() const { return writing_; }
  // The message at the front was written (or abandoned): the next one may start.
  void pop_front();
  // Drops everything but the message being written (a slow client: its close follows).
  void drop_waiting();
  void clear();

 private:
  bool ordered_;
  bool writing_ = false;
  std::deque<Outgoing> queue_;
  size_t bytes_ = 0;
};

}  // namespace grotto::server
