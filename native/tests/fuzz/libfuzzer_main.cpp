// libFuzzer driver (built by scripts/fuzz.sh with clang, ASan and UBSan).
#include <cstdlib>
#include <string>

#include "fuzz_intake.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string scratch = [] {
    const char* dir = std::getenv("SURFMAP_FUZZ_SCRATCH");
    return std::string(dir ? dir : "/tmp");
  }();
  surfmap::fuzz::run_intake_input(data, size, scratch);
  return 0;
}
