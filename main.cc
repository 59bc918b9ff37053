#include "cli/registry.h"

int main(int argc, char** argv) { return lpvid::cli::run_main(argc, argv); }
