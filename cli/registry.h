#pragma once
namespace lpvid::cli {
int run_main(int argc, char** argv);
}
