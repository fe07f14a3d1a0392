// grotto-load: the headless load tool (client/load/load.hpp). The report goes to stdout, logs and
// the progress line to stderr; --json writes every figure. The exit code gates a deployment:
// 0 pass, 1 errors, 2 invalid flags, 3 too many stalls (report.hpp).
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>

#include "client/load/load.hpp"

int main(int argc, char** argv) {
  namespace load = grotto::load;
  auto cli = load::parse_command_line(argc, argv);
  if (!cli.run) {
    std::fprintf(cli.exit_code == 0 ? stdout : stderr, "%s\n", cli.text.c_str());
    return cli.exit_code;
  }
  auto logger = spdlog::stderr_color_mt("grotto-load");
  spdlog::set_default_logger(logger);
  spdlog::set_level(spdlog::level::from_str(cli.log_level));

  cli.options.progress = !cli.quiet && isatty(STDERR_FILENO) == 1;
  auto report = load::run_load(cli.options);
  if (!report) {
    std::fprintf(stderr, "grotto-load: %s\n", report.error().message.c_str());
    return report.error().code == grotto::ErrorCode::kInvalidArgument ? load::kExitBadFlags
                                                                      : load::kExitErrors;
  }
  if (!cli.quiet) std::fputs(load::format_table(*report).c_str(), stdout);
  if (!cli.json_path.empty()) {
    std::ofstream file(cli.json_path);
    file << load::to_json_text(*report) << "\n";
    if (!file) {
      std::fprintf(stderr, "grotto-load: cannot write --json %s\n", cli.json_path.c_str());
      return load::kExitErrors;
    }
  }
  return load::exit_code(*report);
}
