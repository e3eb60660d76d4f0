// surfmap compare ... / surfmap batch ...: these commands are written in
// Python (the package's surfmap.compare and surfmap.batch modules, which use
// numpy, matplotlib and Dask); the C++ program replaces itself with
// `python3 -m surfmap.<module> ARGS...` with the package on PYTHONPATH
// (docs/many_shapes.md). The package is found at $SURFMAP_PYTHONPATH, else
// beside the program (<bin>/../python, the build tree's layout), else at the
// build directory this program was configured with.
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "commands.h"
#include "surfmap/error.h"

#ifndef SURFMAP_PYTHON_EXECUTABLE
#define SURFMAP_PYTHON_EXECUTABLE "python3"
#endif
#ifndef SURFMAP_PYTHON_PACKAGE_DIR
#define SURFMAP_PYTHON_PACKAGE_DIR ""
#endif

namespace surfmap::cli {
namespace {

namespace fs = std::filesystem;

std::string python_package_dir() {
  if (const char* env = std::getenv("SURFMAP_PYTHONPATH"); env && *env) return env;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path beside = exe.parent_path().parent_path() / "python";
    if (fs::exists(beside / "surfmap" / "__init__.py", ec)) return beside.string();
  }
  const std::string built = SURFMAP_PYTHON_PACKAGE_DIR;
  if (!built.empty() && fs::exists(fs::path(built) / "surfmap" / "__init__.py", ec)) return built;
  throw InputError("cannot find the surfmap Python package (set SURFMAP_PYTHONPATH to the folder holding surfmap/)");
}

void register_python_command(CLI::App& app, const std::string& name, const std::string& help) {
  auto* cmd = app.add_subcommand(name, help + " (Python: surfmap." + name + "; --help there)");
  cmd->prefix_command();
  cmd->allow_extras();
  cmd->set_help_flag();
  cmd->callback([cmd, name] { exec_python_module(name, cmd->remaining()); });
}

}  // namespace

[[noreturn]] void exec_python_module(const std::string& module, const std::vector<std::string>& args) {
  const std::string dir = python_package_dir();
  const char* old = std::getenv("PYTHONPATH");
  const std::string path = old && *old ? dir + ":" + old : dir;
  setenv("PYTHONPATH", path.c_str(), 1);
  const char* python = std::getenv("SURFMAP_PYTHON");
  if (!python || !*python) python = SURFMAP_PYTHON_EXECUTABLE;
  std::vector<std::string> argv_s = {python, "-m", "surfmap." + module};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& s : argv_s) argv.push_back(s.data());
  argv.push_back(nullptr);
  execvp(python, argv.data());
  throw Error(std::string("cannot run ") + python + ": " + std::strerror(errno));
}

void register_python_commands(CLI::App& app) {
  register_python_command(app, "compare", "Distance table of shapes through a common domain or pairwise maps");
  register_python_command(app, "batch", "Many map or comparison jobs on a Dask cluster (local by default)");
}

}  // namespace surfmap::cli
