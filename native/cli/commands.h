#pragma once
// Each subcommand lives in cli/cmd_<name>.cpp and registers itself on the app.
// A command's callback throws surfmap::Error on bad input; main() turns any
// exception into a one-line message and a non-zero exit status.
#include <string>
#include <vector>

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

/// Replaces this process with `python3 -m surfmap.<module> ARGS...`, the
/// package on PYTHONPATH (cmd_python.cpp); throws when it cannot start.
[[noreturn]] void exec_python_module(const std::string& module, const std::vector<std::string>& args);

}  // namespace surfmap::cli
