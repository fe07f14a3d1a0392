// name_this_thread: the name the operating system shows for the thread (top -H, ps -L, perf), cut
// to Linux's 15 bytes.
#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <thread>

#include <sys/syscall.h>
#include <unistd.h>

#include "common/core/thread_name.hpp"

namespace grotto {
namespace {

std::string own_name() {
  std::ifstream comm("/proc/self/task/" + std::to_string(::syscall(SYS_gettid)) + "/comm");
  std::string name;
  std::getline(comm, name);
  return name;
}

TEST(ThreadName, names_the_calling_thread_and_cuts_long_names) {
  std::string short_name, long_name;
  std::thread([&] {
    name_this_thread("grotto-build");
    short_name = own_name();
    name_this_thread("a-name-longer-than-fifteen-bytes");
    long_name = own_name();
  }).join();
  EXPECT_EQ(short_name, "grotto-build");
  EXPECT_EQ(long_name, "a-name-longer-t");
}

}  // namespace
}  // namespace grotto
