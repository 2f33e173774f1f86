#pragma once
// Instruction-set dispatch of the front-end kernels (integral images, Harris, ZNCC, appearance prediction).
//
// Each kernel has a plain C++ version and, on x86-64, an SSE2 version (the x86-64 baseline; the appearance
// prediction has none: it runs its plain version there). The integral images, Harris and the appearance prediction
// also have an AVX2 version, compiled with __attribute__((target("avx2"))) and chosen at run time, so the build
// needs no -march flag and runs on any x86-64 CPU. Every level gives bit-identical results: the same exact integer
// sums, then the same sequence of double operations (no FMA).
// The level is process-wide. It starts at the best level the CPU supports; tests and benchmarks lower it to exercise
// the other paths. AVX2 kernels clear the upper register halves (vzeroupper) before any plain SSE code runs: left
// dirty, they slow every later SSE instruction of the process down, twofold here.
namespace rtslam::vision {

enum class SimdLevel { scalar = 0, sse2 = 1, avx2 = 2 };

/// The best level this CPU (and build) supports.
SimdLevel best_simd_level();
/// The level the kernels use now.
SimdLevel simd_level();
/// Selects a level, clamped to best_simd_level(); returns the level in use. Do not call it while other threads run
/// vision kernels (they would mix levels, which is harmless but makes timings meaningless).
SimdLevel set_simd_level(SimdLevel level);
/// "scalar", "sse2" or "avx2".
const char* to_string(SimdLevel level);

}  // namespace rtslam::vision
