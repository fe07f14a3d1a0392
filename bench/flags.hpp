// Flag parsing the benchmark programs share, with every Grotto binary's conventions: --help prints
// the usage and exits 0; a bad or unknown flag prints what was wrong and exits 2.
#pragma once

#include <CLI/CLI.hpp>

#include <optional>

namespace grotto::bench {

// Parses argv into app; the exit code to return when the program should stop (help, bad flag).
inline std::optional<int> parse_flags(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  return std::nullopt;
}

}  // namespace grotto::bench
