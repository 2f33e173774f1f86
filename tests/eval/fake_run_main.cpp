// eval_fake_run: `eval_fake_run run --seed N --out DIR [--duration S] [--fail-seed K] [--cov-scale C]`, the
// command-line contract of `rtslam run` for the batch tests (see fake_run.hpp). Exits 3 without output for the
// seed given by --fail-seed, to test failure handling.
#include <cstdlib>
#include <iostream>
#include <string>

#include "eval/fake_run.hpp"

int main(int argc, char** argv) {
  rtslam::eval::test::FakeRunOptions o;
  std::string out;
  long long fail_seed = -1;
  if (argc < 2 || std::string(argv[1]) != "run") {
    std::cerr << "usage: eval_fake_run run --seed N --out DIR [--duration S]\n";
    return 2;
  }
  for (int i = 2; i < argc; i += 2) {
    if (std::string(argv[i]) == "--force") {  // a flag: rtslam run replaces an earlier run's files
      --i;
      continue;
    }
    if (i + 1 >= argc) break;
    const std::string k = argv[i], v = argv[i + 1];
    if (k == "--seed") o.seed = std::stoull(v);
    else if (k == "--out") out = v;
    else if (k == "--duration") o.duration_s = std::stod(v);
    else if (k == "--fail-seed") fail_seed = std::stoll(v);
    else if (k == "--cov-scale") o.cov_scale = std::stod(v);
    else if (k == "--config" || k == "--dataset") continue;
    else {
      std::cerr << "eval_fake_run: unknown option " << k << '\n';
      return 2;
    }
  }
  if (out.empty()) return 2;
  if (static_cast<long long>(o.seed) == fail_seed) {
    std::cerr << "eval_fake_run: failing on purpose for seed " << o.seed << '\n';
    return 3;
  }
  std::cout << "eval_fake_run: " << rtslam::eval::test::write_fake_run(out, o) << " poses into " << out << '\n';
  return 0;
}
