// The room tier's HTTP client (server/room_tier.hpp) against a scripted HTTP server on loopback
// (plain POSIX sockets, one connection at a time): answers and their bytes, keep-alive reuse, a
// kept-alive connection the server closed, statuses other than 200, a body over the limit, a
// peer that accepts and never answers, nobody listening, bad URLs. Waits are bounded; nothing
// asserts a duration.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <future>
#include <string>
#include <thread>
#include <vector>

#include "server/room_tier.hpp"

namespace grotto::server {
namespace {

using namespace std::chrono_literals;

// What the scripted server does with each request on a connection, in order.
enum class Reply { kRoom, kRoomThenClose, kNotFound, kHuge, kSilent };

class ScriptedServer {
 public:
  explicit ScriptedServer(std::vector<std::vector<Reply>> connections)
      : connections_(std::move(connections)) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
    EXPECT_EQ(::listen(fd_, 8), 0);
    socklen_t len = sizeof addr;
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&addr), &len);
    port_ = ntohs(addr.sin_port);
    thread_ = std::thread([this] { run(); });
  }
  ~ScriptedServer() {
    stop_ = true;
    ::shutdown(fd_, SHUT_RDWR);
    ::close(fd_);
    thread_.join();
  }
  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_); }
  int accepted() const { return accepted_.load(); }
  std::vector<std::string> targets() const {
    std::lock_guard lock(mutex_);
    return targets_;
  }
  std::vector<std::string> priorities() const {
    std::lock_guard lock(mutex_);
    return priorities_;
  }
  std::vector<std::string> authorizations() const {
    std::lock_guard lock(mutex_);
    return authorizations_;
  }

 private:
  void run() {
    for (const std::vector<Reply>& script : connections_) {
      int c = ::accept(fd_, nullptr, nullptr);
      if (c < 0 || stop_) return;
      ++accepted_;
      serve(c, script);
      ::close(c);
    }
  }
  void serve(int c, const std::vector<Reply>& script) {
    std::string pending;
    for (Reply reply : script) {
      // One request: up to the blank line (no bodies).
      while (pending.find("\r\n\r\n") == std::string::npos) {
        char buf[1024];
        ssize_t n = ::recv(c, buf, sizeof buf, 0);
        if (n <= 0) return;
        pending.append(buf, static_cast<size_t>(n));
      }
      const size_t end = pending.find("\r\n\r\n") + 4;
      const std::string request = pending.substr(0, end);
      pending.erase(0, end);
      {
        std::lock_guard lock(mutex_);
        targets_.push_back(request.substr(4, request.find(' ', 4) - 4));
        const size_t auth = request.find("Authorization: ");
        authorizations_.push_back(
            auth == std::string::npos
                ? ""
                : request.substr(auth + 15, request.find("\r\n", auth) - auth - 15));
        const size_t at = request.find("Grotto-Priority: ");
        priorities_.push_back(at == std::string::npos
                                  ? ""
                                  : request.substr(at + 17, request.find("\r\n", at) - at - 17));
      }
      std::string answer;
      switch (reply) {
        case Reply::kRoom:
        case Reply::kRoomThenClose:
          answer = "HTTP/1.1 200 OK\r\nContent-Length: 5\r\n\r\nROOM!";
          break;
        case Reply::kNotFound:
          answer = "HTTP/1.1 404 Not Found\r\nContent-Length: 23\r\n\r\nno room 0.0.0.r9 here\r\n";
          break;
        case Reply::kHuge:
          answer = "HTTP/1.1 200 OK\r\nContent-Length: 100000\r\n\r\n" + std::string(100000, 'x');
          break;
        case Reply::kSilent: {
          char buf[64];  // holds the connection, answers nothing, until the client gives up
          while (!stop_ && ::recv(c, buf, sizeof buf, 0) > 0) {
          }
          return;
        }
      }
      ::send(c, answer.data(), answer.size(), MSG_NOSIGNAL);
      if (reply == Reply::kRoomThenClose) return;
    }
    // Script done: wait for the client to close, so a reused connection is not cut early.
    char buf[64];
    while (!stop_ && ::recv(c, buf, sizeof buf, 0) > 0) {
    }
  }

  std::vector<std::vector<Reply>> connections_;
  int fd_ = -1;
  uint16_t port_ = 0;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<int> accepted_{0};
  mutable std::mutex mutex_;
  std::vector<std::string> targets_;
  std::vector<std::string> priorities_;      // each request's Grotto-Priority
  std::vector<std::string> authorizations_;  // and its Authorization
};

std::unique_ptr<RoomTier> tier(const std::string& url, size_t max_body = size_t{4} << 20,
                               const std::string& token = "") {
  RoomTierConfig c;
  c.url = url;
  c.token = token;
  c.path_of = [](const RoomKey& key) { return "/rooms/" + key.id.to_string(); };
  c.max_body_bytes = max_body;
  auto t = RoomTier::create(c);
  EXPECT_TRUE(t.ok()) << (t.ok() ? "" : t.error().message);
  return t.ok() ? std::move(t).value() : nullptr;
}

RoomKey key(uint32_t index) {
  RoomKey k;
  k.id = cave::RoomId::interior({0, 0, 0}, index);
  return k;
}

// One fetch, waited for (the bound is the test's, far above the fetch's own timeout).
Result<std::vector<uint8_t>> fetch(RoomTier& t, RoomKey k, std::chrono::milliseconds timeout = 5s) {
  std::promise<Result<std::vector<uint8_t>>> answer;
  auto got = answer.get_future();
  t.fetch(k, 250, timeout, [&](Result<std::vector<uint8_t>> r) { answer.set_value(std::move(r)); });
  EXPECT_EQ(got.wait_for(60s), std::future_status::ready);
  return got.get();
}

std::string text(const Result<std::vector<uint8_t>>& r) {
  return r ? std::string(r->begin(), r->end()) : "error: " + r.error().message;
}

TEST(RoomTier, answers_come_back_byte_for_byte_over_one_kept_alive_connection) {
  ScriptedServer server({{Reply::kRoom, Reply::kRoom, Reply::kRoom}});
  auto t = tier(server.url());
  ASSERT_TRUE(t);
  for (uint32_t i = 0; i < 3; ++i)
    EXPECT_EQ(text(fetch(*t, key(i))), "ROOM!");
  EXPECT_EQ(server.accepted(), 1);
  EXPECT_EQ(server.targets(),
            (std::vector<std::string>{"/rooms/0.0.0.r0", "/rooms/0.0.0.r1", "/rooms/0.0.0.r2"}));
  // How soon each room is needed goes to the owner, which queues it by that.
  EXPECT_EQ(server.priorities(), (std::vector<std::string>{"250", "250", "250"}));
  EXPECT_EQ(server.authorizations(), (std::vector<std::string>{"", "", ""})) << "no token";
}

TEST(RoomTier, the_clusters_token_goes_to_the_owner) {
  ScriptedServer server({{Reply::kRoom}});
  auto t = tier(server.url(), size_t{4} << 20, "s3cret");
  ASSERT_TRUE(t);
  EXPECT_EQ(text(fetch(*t, key(0))), "ROOM!");
  EXPECT_EQ(server.authorizations(), std::vector<std::string>{"Bearer s3cret"});
}

TEST(RoomTier, a_connection_the_server_closed_is_replaced_without_an_error) {
  ScriptedServer server({{Reply::kRoomThenClose}, {Reply::kRoom}});
  auto t = tier(server.url());
  ASSERT_TRUE(t);
  EXPECT_EQ(text(fetch(*t, key(0))), "ROOM!");
  // The first connection looks alive to the client (no Connection: close) but is gone.
  std::this_thread::sleep_for(50ms);
  EXPECT_EQ(text(fetch(*t, key(1))), "ROOM!");
  EXPECT_EQ(server.accepted(), 2);
}

TEST(RoomTier, other_statuses_and_long_bodies_are_errors_that_say_what_came) {
  ScriptedServer server({{Reply::kNotFound, Reply::kHuge}});
  auto t = tier(server.url(), 1000);
  ASSERT_TRUE(t);
  auto missing = fetch(*t, key(9));
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("404"), std::string::npos) << missing.error().message;
  EXPECT_NE(missing.error().message.find("no room 0.0.0.r9 here"), std::string::npos);
  auto huge = fetch(*t, key(1));
  ASSERT_FALSE(huge.ok()) << huge->size();
  EXPECT_NE(huge.error().message.find("body limit exceeded"), std::string::npos)
      << huge.error().message;
}

TEST(RoomTier, a_peer_that_accepts_and_never_answers_times_out_and_others_still_get_answers) {
  ScriptedServer server({{Reply::kSilent}, {Reply::kRoom}});
  auto t = tier(server.url());
  ASSERT_TRUE(t);
  auto late = fetch(*t, key(0), 200ms);
  ASSERT_FALSE(late.ok());
  EXPECT_NE(late.error().message.find("no answer"), std::string::npos) << late.error().message;
  EXPECT_EQ(text(fetch(*t, key(1))), "ROOM!");
}

TEST(RoomTier, nobody_listening_is_an_error_naming_the_address) {
  int port = 0;
  {
    ScriptedServer gone({});  // bound, then closed: nothing listens on its port afterwards
    port = std::stoi(gone.url().substr(gone.url().rfind(':') + 1));
  }
  auto t = tier("http://127.0.0.1:" + std::to_string(port));
  ASSERT_TRUE(t);
  auto r = fetch(*t, key(0), 2s);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("127.0.0.1:" + std::to_string(port)), std::string::npos)
      << r.error().message;
}

TEST(RoomTier, bad_urls_are_refused_by_name) {
  for (const char* url : {"https://a:1", "http://a", "http://a:0", "http://a:99999", "http://a:1/x",
                          "a:1", "http://:80"}) {
    RoomTierConfig c;
    c.url = url;
    c.path_of = [](const RoomKey&) { return "/"; };
    auto t = RoomTier::create(c);
    ASSERT_FALSE(t.ok()) << url;
    EXPECT_NE(t.error().message.find(url), std::string::npos) << t.error().message;
  }
  EXPECT_TRUE(parse_tier_url("http://[::1]:8080/").ok());
}

}  // namespace
}  // namespace grotto::server
