#pragma once
// Names the calling thread for the operating system, so that `top -H`, `ps -L`, perf and gdb tell
// a server's generation workers from its I/O threads and a client's decoders. Linux keeps 15
// bytes; a longer name is cut. Elsewhere it does nothing.
#include <algorithm>
#include <cstring>
#include <string_view>

#if defined(__linux__)
#include <pthread.h>
#endif

namespace grotto {

inline void name_this_thread(std::string_view name) {
#if defined(__linux__)
  char text[16] = {};
  std::memcpy(text, name.data(), std::min(name.size(), sizeof text - 1));
  pthread_setname_np(pthread_self(), text);
#else
  (void)name;
#endif
}

}  // namespace grotto
