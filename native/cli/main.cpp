// The `surfmap` command-line program. Exit status: 0 success, 1 invalid input
// or failed solve (one-line message on stderr), 2 bad command line.
#include <exception>
#include <iostream>

#include "commands.h"
#include "surfmap/error.h"

int main(int argc, char** argv) {
  CLI::App app{"surfmap: globally optimal maps between closed surfaces of equal genus"};
  app.require_subcommand(1);
  surfmap::cli::register_info(app);
  surfmap::cli::register_loops(app);
  surfmap::cli::register_map(app);
  surfmap::cli::register_uniformize(app);
  surfmap::cli::register_generate(app);
  surfmap::cli::register_domain(app);
  surfmap::cli::register_python_commands(app);
  surfmap::cli::register_verify(app);
  // SURFMAP_CLI_REGISTER (keep this marker: add one register_* call per line above it)
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  } catch (const surfmap::Cancelled& e) {
    std::cerr << "surfmap: cancelled: " << e.what() << "\n";
    return 1;
  } catch (const surfmap::Error& e) {
    std::cerr << "surfmap: error: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "surfmap: internal error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
