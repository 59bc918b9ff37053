// libFuzzer entry point for one reader, chosen at compile time by
// LPVID_FUZZ_READER (fuzz/README.md; CMake builds one executable per reader).
#include <cstddef>
#include <cstdint>

#include "fuzz/readers.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  lpvid::fuzz::read_bytes(lpvid::fuzz::Reader::LPVID_FUZZ_READER, data, size);
  return 0;
}
