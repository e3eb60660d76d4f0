#pragma once
// Each subcommand lives in cli/cmd_<name>.cpp and registers itself on the app.
// A command's callback throws surfmap::Error on bad input; main() turns any
// exception into a one-line message and a non-zero exit status.
#include <CLI/CLI.hpp>

namespace surfmap::cli {

void register_info(CLI::App& app);
void register_loops(CLI::App& app);
void register_uniformize(CLI::App& app);
void register_generate(CLI::App& app);
void register_map(CLI::App& app);
void register_domain(CLI::App& app);
void register_python_commands(CLI::App& app);  // compare, batch
void register_verify(CLI::App& app);

}  // namespace surfmap::cli
