#pragma once
// ZNCC patch matching (paper, "Image processing"; MATH.md).
//
// Score of a template a (n pixels) at position p of image b (the patch centred on pixel p):
//   zncc = Σ (a - ā)(b - b̄) / sqrt(Σ (a - ā)² Σ (b - b̄)²) = (n Σab - Σa Σb) / sqrt((n Σa² - (Σa)²)(n Σb² - (Σb)²)),
// computed from exact integer sums (Σa, Σa² precomputed; Σb, Σb² from integral images of the search region in an
// exhaustive search, else summed from the window's rows) with one rounding at the end. A uniform image window (zero
// variance) scores 0; a uniform template cannot be matched. Every SIMD level (simd.hpp) gives identical results.
//
// Search: every integer position inside an ellipse (the n-sigma innovation ellipse, (p - c)ᵀ Σ⁻¹ (p - c) <= n²) or
// inside a box; positions outside are not evaluated. Either exhaustive (raster order) or two-level:
//  1. half resolution: the image around the region and the template are reduced by 2 with a [1 2 1] x [1 2 1]
//     kernel (a 15x15 template gives 7x7 samples centred on its odd pixels, so on its centre); every second
//     position in u and v is scored with the reduced template;
//  2. full resolution: a hill climb, until no position of the (2r + 1)² neighbourhood (r = climb_radius, default 2)
//     is better, from every coarse local maximum (8-neighbourhood of the coarse grid) scoring at least
//     max(threshold - coarse_margin, best coarse score - coarse_candidates_spread), in decreasing coarse score; the
//     best end point wins. Several starts resolve repeated structures (near-equal peaks far apart) like the
//     exhaustive search; the wider climb steps over the small local maxima of sharp, noisy images.
// Defaults were chosen on the real sequences (tests/vision/test_zncc.cpp, docs/vision.md): the two-level result equals
// the exhaustive one on > 99.5 % of tracked patches.
// The best position is the FIRST maximum in evaluation order; it is a match if its score reaches `threshold`. When
// there is no match, the result carries only found = false and the counters (no position, no score).
// Bounded partial correlation (Di Stefano et al. 2005), at full resolution: every partial_step_rows template rows,
// the remaining rows R are bounded with centred terms, Σ_R ab <= sqrt((m Σ_R a² - (Σ_R a)²)(m Σ_R b² - (Σ_R b)²)) / m
// + Σ_R a Σ_R b / m (m pixels in R; Cauchy-Schwarz on the centred rows plus the exact mean term), and a position is
// abandoned when the bound on its score is strictly below the floor it has to beat. The floor is chosen so that
// pruning never changes the result, only the time:
//  - exhaustive: max(threshold, best so far);
//  - two-level climb: the climb's current score (a step needs a strictly better position). A position remembers
//    the floor it fell below, and is computed again only if asked against a lower floor.
// The bound carries a 1e-12 safety margin against floating-point rounding. The half-resolution pass does not prune
// (its 7-row templates cost less than the bounds); it skips the square root of positions clearly below its floor
// max(threshold - coarse_margin, best so far - coarse_candidates_spread), identically with or without pruning.
//
// Sub-pixel: a 2D quadratic fit of the scores of the 3x3 neighbourhood of the best position (the neighbours are
// computed in full for the fit, even if they lie outside the ellipse); separable parabolas as fallback.
// Pixel convention: see image.hpp. Positions are patch CENTRES.
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "rtslam/core/yaml.hpp"
#include "rtslam/vision/image.hpp"
#include "rtslam/vision/integral.hpp"

namespace rtslam::vision {

/// A square template of odd size with its sums precomputed for ZNCC and bounded partial correlation.
class Patch {
 public:
  /// Copies a square view of odd size (throws InvariantError otherwise: a caller bug).
  void assign(ImageView src);
  /// Copies the size x size patch centred on pixel (u, v); false (patch unchanged) if it does not fit the image.
  bool extract(ImageView image, int u, int v, int size);

  int size() const { return size_; }
  int half() const { return size_ / 2; }
  const std::uint8_t* data() const { return pixels_.data(); }
  ImageView view() const { return ImageView{pixels_.data(), size_, size_, size_}; }
  std::int64_t sum() const { return sum_; }
  std::int64_t sum_sq() const { return sum_sq_; }
  /// n Σa² - (Σa)² (zero for a uniform template).
  std::int64_t centred_energy() const { return energy_; }
  /// Sums over the rows [r, size) (index r in [0, size]).
  std::int64_t suffix_sum(int r) const { return suffix_sum_[static_cast<std::size_t>(r)]; }
  std::int64_t suffix_sq(int r) const { return suffix_sq_[static_cast<std::size_t>(r)]; }

  /// The template as int16 rows zero-padded to padded_stride() (a multiple of 16) entries, for vectorized dots.
  const std::int16_t* padded_data() const { return padded_.data(); }
  int padded_stride() const { return padded_stride_; }

  /// The half-resolution template: size()/2 x size()/2 [1 2 1]² weighted sums centred on the odd pixels, as int16
  /// rows zero-padded to half_stride() (a multiple of 8) entries.
  int half_size() const { return size_ / 2; }
  const std::int16_t* half_data() const { return half_.data(); }
  int half_stride() const { return half_stride_; }
  std::int64_t half_sum() const { return half_suffix_sum_[0]; }
  std::int64_t half_energy() const { return half_energy_; }
  std::int64_t half_suffix_sum(int r) const { return half_suffix_sum_[static_cast<std::size_t>(r)]; }
  std::int64_t half_suffix_sq(int r) const { return half_suffix_sq_[static_cast<std::size_t>(r)]; }

 private:
  void precompute();

  int size_ = 0;
  std::vector<std::uint8_t> pixels_;
  std::int64_t sum_ = 0, sum_sq_ = 0, energy_ = 0;
  std::vector<std::int64_t> suffix_sum_, suffix_sq_;
  std::vector<std::int16_t> padded_;
  int padded_stride_ = 0;
  std::vector<std::int16_t> half_;
  int half_stride_ = 0;
  std::int64_t half_energy_ = 0;
  std::vector<std::int64_t> half_suffix_sum_, half_suffix_sq_;
};

/// The region of patch centres to search: the ellipse (p - centre)ᵀ inv_cov (p - centre) <= n_sigma², or, with
/// box_only, the box |u - cu| <= box_half.x, |v - cv| <= box_half.y.
struct SearchEllipse {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  Eigen::Matrix2d inv_cov = Eigen::Matrix2d::Identity();  // px⁻²
  double n_sigma = 3.0;
  bool box_only = false;
  Eigen::Vector2d box_half = Eigen::Vector2d::Zero();  // px, with box_only

  /// From a 2x2 covariance (px²), e.g. the innovation covariance of an observation.
  static SearchEllipse from_covariance(const Eigen::Vector2d& centre, const Eigen::Matrix2d& cov, double n_sigma);
  /// The rectangle |u - cu| <= half_w, |v - cv| <= half_h (every position evaluated).
  static SearchEllipse box(const Eigen::Vector2d& centre, double half_w, double half_h);

  bool contains(double u, double v) const;
  /// Integer positions of the bounding box (may extend beyond the image).
  Roi bounding_box() const;
};

struct ZnccOptions {
  double threshold = 0.90;          // minimum score of a match (RT-SLAM MATCH_TH), in [-1, 1]
  int patch_size = 15;              // odd, in [5, 31]; the size of the templates this matcher expects
  bool two_level = true;            // half-resolution pass, then full-resolution climb
  bool partial_correlation = true;  // bounded partial correlation (never changes the result)
  double coarse_margin = 0.20;      // two-level: a coarse start must score >= threshold - coarse_margin (>= 0)
  double coarse_candidates_spread = 0.10;  // two-level: climb from every coarse local maximum >= best - spread
  int climb_radius = 2;             // two-level: a climb step looks at the (2r + 1)² neighbourhood, r in [1, 3]
  int partial_step_rows = 4;        // rows between two bound checks (>= 1)

  /// `where` names the options in messages (their config section, e.g. "search/zncc", or the file and section).
  void validate(const std::string& where = "zncc options") const;
  /// Keys: threshold, patch_size, two_level, partial_correlation, coarse_margin, coarse_candidates_spread,
  /// climb_radius, partial_step_rows.
  static ZnccOptions from_yaml(YamlMap& map);
  /// The keys of from_yaml with their values.
  YAML::Node to_yaml() const;
};

struct MatchResult {
  bool found = false;   // best score >= threshold
  int u_px = 0;         // integer position of the best score (patch centre)
  int v_px = 0;
  double u = 0.0;       // sub-pixel position (only refined when found)
  double v = 0.0;
  double score = -2.0;  // score at (u_px, v_px) (only when found)
  int n_evaluated = 0;  // search positions whose correlation was started
  int n_pruned = 0;     // of those, abandoned by bounded partial correlation
};

/// Full-resolution scores of ONE template in ONE image, remembered across match() calls: the one-point RANSAC
/// hypotheses search each landmark in small, overlapping boxes, and the score of a template at a position does not
/// depend on the search that asks for it. An entry is either the exact score or the floor a position was abandoned
/// below (bounded partial correlation), exactly as match() keeps them within one call, so a search with a memo
/// returns what it returns without one (found, position, score, sub-pixel) and computes fewer windows (its
/// n_evaluated counts only the windows it computed). The caller clears the memo when the template or the image
/// changes. Open addressing over a fixed capacity (no allocation after construction); a full memo stops
/// remembering, never forgets wrongly.
class ScoreMemo {
 public:
  /// Holds nothing until reserve(): remembers nothing, and a search with it computes every window.
  ScoreMemo() = default;
  explicit ScoreMemo(int capacity) { reserve(capacity); }
  /// Room for `capacity` entries (rounded up to a power of two; half of it is used before the memo stops
  /// remembering); forgets every entry. The only allocation.
  void reserve(int capacity);
  /// Forgets every entry (O(1)).
  void clear();
  /// What is remembered at (u, v): false if nothing; else `exact` tells whether `value` is the exact score or a
  /// floor the score is below.
  bool lookup(int u, int v, double& value, bool& exact) const;
  /// Remembers the exact score at (u, v), or (exact false) that it scores below `value`. An exact score is never
  /// replaced; a floor only by a lower floor or the exact score.
  void remember(int u, int v, double value, bool exact);
  int size() const { return size_; }
  int capacity() const { return static_cast<int>(entries_.size()); }

 private:
  struct Entry {
    std::uint64_t key = 0;
    double value = 0.0;            // the exact score, or the floor
    std::uint32_t generation = 0;  // valid when equal to generation_
    bool is_exact = false;
  };
  static constexpr std::size_t npos = static_cast<std::size_t>(-1);
  std::size_t home(std::uint64_t key) const;
  std::size_t slot(std::uint64_t key) const;
  std::vector<Entry> entries_;
  std::uint32_t generation_ = 1;
  int size_ = 0;
};

/// Matches templates in images. Holds reusable buffers (integral images, half-resolution image and tables, score map):
/// no allocation once they have grown; use one matcher per thread.
class ZnccMatcher {
 public:
  explicit ZnccMatcher(ZnccOptions options = {});
  const ZnccOptions& options() const { return options_; }

  /// Searches `patch` (of size options().patch_size) in `image` over `region`. Positions whose patch would leave
  /// the image are not evaluated. With a memo (of this patch in this image), remembered full-resolution scores are
  /// reused and new ones remembered; the result is the same as without.
  MatchResult match(const Patch& patch, ImageView image, const SearchEllipse& region, ScoreMemo* memo = nullptr);

  /// Grows the buffers to what any search region of bounding-box area <= max_area_px2 in an image of
  /// width x height needs, so that match() allocates nothing afterwards (call once the image size is known).
  void reserve(double max_area_px2, int width, int height);

 private:
  ZnccOptions options_;
  IntegralImages integral_;  // exhaustive search only
  enum : std::uint8_t { kUnset = 0, kExact = 1, kBelow = 2 };
  struct Candidate {
    double score;
    int u, v;
  };
  std::vector<double> scores_;          // per position of the search box: exact score, or the floor it fell below
  std::vector<std::uint8_t> state_;     // kUnset, kExact or kBelow per position
  std::vector<double> coarse_;          // half-resolution scores
  std::vector<Candidate> candidates_;   // climb starts
  std::vector<std::uint16_t> half_rows_;  // horizontally reduced rows around the search box
  std::vector<std::int16_t> half_;      // half-resolution image ([1 2 1]² sums) around the search box
  std::vector<std::uint32_t> half_sum_;  // its integral images (modulo 2^32, exact for template-sized windows)
  std::vector<std::uint32_t> half_sq_;
  std::vector<std::uint32_t> half_dots_;  // Σ ab at one row of coarse positions
};

}  // namespace rtslam::vision
