#pragma once
// The layout of one state block: a short sequence of Euclidean and unit-quaternion segments.
// Ambient size: what the mean stores (a quaternion is 4 numbers [qw qx qy qz]); tangent size: its covariance
// rows (a quaternion has 3, δθ). Retraction per segment: Euclidean x ⊕ δ = x + δ; quaternion q ⊕ δθ = q ⊗ Exp(δθ)
// (right perturbation, ../shared/MATH.md "Rotations").
#include <array>
#include <cstdint>
#include <string>

#include <Eigen/Core>

namespace rtslam::filter {

class BlockLayout {
 public:
  static constexpr int kMaxSegments = 8;
  enum class Kind : std::uint8_t { Euclidean, Quaternion };

  BlockLayout() = default;
  static BlockLayout euclidean(int n) { return BlockLayout().then_euclidean(n); }
  static BlockLayout quaternion() { return BlockLayout().then_quaternion(); }
  BlockLayout& then_euclidean(int n);
  BlockLayout& then_quaternion();

  int ambient_size() const { return ambient_; }
  int tangent_size() const { return tangent_; }
  int segment_count() const { return count_; }

  /// x ⊕ dx in place on one block's ambient mean; segments whose δ is exactly zero are left bit-identical.
  void boxplus(Eigen::Ref<Eigen::VectorXd> x, const Eigen::Ref<const Eigen::VectorXd>& dx) const;
  /// x1 ⊖ x0 into dx (tangent size).
  void boxminus(const Eigen::Ref<const Eigen::VectorXd>& x1, const Eigen::Ref<const Eigen::VectorXd>& x0,
                Eigen::Ref<Eigen::VectorXd> dx) const;
  std::string describe() const;

  bool operator==(const BlockLayout& o) const;

 private:
  std::array<Kind, kMaxSegments> kinds_{};
  std::array<std::uint8_t, kMaxSegments> sizes_{};
  int count_ = 0;
  int ambient_ = 0;
  int tangent_ = 0;
};

}  // namespace rtslam::filter
