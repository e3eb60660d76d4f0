// Replays the fuzzer's corpus (tests/fuzz/corpus: hand-made seeds and every
// finding of scripts/fuzz.sh) through the fuzz entry point with the normal
// build: each input must end in "ok" or a one-line InputError; a crash, an
// abort (fuzz_intake.cpp's invariant checks) or another exception fails.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "fuzz/fuzz_intake.h"

namespace surfmap {
namespace {

namespace fs = std::filesystem;

std::vector<fs::path> corpus_files(const std::string& sub) {
  std::vector<fs::path> files;
  const fs::path dir = fs::path(SURFMAP_FUZZ_CORPUS_DIR) / sub;
  if (!fs::is_directory(dir)) return files;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.is_regular_file()) files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  return files;
}

std::string replay(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return fuzz::run_intake_input(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(),
                                fs::temp_directory_path().string());
}

TEST(FuzzCorpus, SeedsGiveTheExpectedOutcome) {
  const auto files = corpus_files("seeds");
  ASSERT_GE(files.size(), 10u) << "seed corpus missing at " << SURFMAP_FUZZ_CORPUS_DIR;
  for (const auto& f : files) {
    const std::string name = f.filename().string(), outcome = replay(f);
    SCOPED_TRACE(name + " -> " + outcome);
    // valid_*: accepted; bad_*: refused with a message (never "ok").
    if (name.rfind("valid_", 0) == 0) EXPECT_EQ(outcome, "ok");
    if (name.rfind("bad_", 0) == 0) EXPECT_NE(outcome, "ok");
  }
}

TEST(FuzzCorpus, EveryFindingEndsInOkOrOneLineError) {
  // Findings are inputs that once crashed, hung or exhausted memory; replaying
  // them must now return (run_intake_input aborts on anything improper).
  const auto files = corpus_files("findings");
  EXPECT_GE(files.size(), 3u);
  for (const auto& f : files) {
    SCOPED_TRACE(f.filename().string());
    const std::string outcome = replay(f);
    EXPECT_FALSE(outcome.empty());
    EXPECT_EQ(outcome.find('\n'), std::string::npos);
  }
}

}  // namespace
}  // namespace surfmap

namespace surfmap {
namespace {

TEST(FuzzCorpus, MinimisedFuzzedCorpusEndsInOkOrOneLineError) {
  // corpus/fuzzed: the libFuzzer corpus of a clean scripts/fuzz.sh run,
  // minimised with -merge=1 (one input per coverage feature): a cheap replay
  // of many reader and intake paths with the g++ build.
  const auto files = corpus_files("fuzzed");
  EXPECT_GE(files.size(), 100u);
  int accepted = 0;
  for (const auto& f : files) {
    const std::string outcome = replay(f);
    ASSERT_EQ(outcome.find('\n'), std::string::npos) << f.filename();
    accepted += outcome == "ok";
  }
  EXPECT_GT(accepted, 0);  // the corpus reaches valid meshes too
}

}  // namespace
}  // namespace surfmap
