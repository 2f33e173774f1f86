#include "rtslam/filter/block_layout.hpp"

#include "rtslam/core/error.hpp"
#include "rtslam/math/rotation.hpp"

namespace rtslam::filter {

BlockLayout& BlockLayout::then_euclidean(int n) {
  RTSLAM_CHECK(count_ < kMaxSegments && n > 0 && n < 256, "bad Euclidean segment");
  kinds_[count_] = Kind::Euclidean;
  sizes_[count_] = static_cast<std::uint8_t>(n);
  ++count_;
  ambient_ += n;
  tangent_ += n;
  return *this;
}

BlockLayout& BlockLayout::then_quaternion() {
  RTSLAM_CHECK(count_ < kMaxSegments, "too many segments");
  kinds_[count_] = Kind::Quaternion;
  sizes_[count_] = 4;
  ++count_;
  ambient_ += 4;
  tangent_ += 3;
  return *this;
}

void BlockLayout::boxplus(Eigen::Ref<Eigen::VectorXd> x, const Eigen::Ref<const Eigen::VectorXd>& dx) const {
  int a = 0;
  int t = 0;
  for (int s = 0; s < count_; ++s) {
    if (kinds_[s] == Kind::Quaternion) {
      const Eigen::Vector3d d = dx.segment<3>(t);
      if (!d.isZero(0.0)) {
        const auto q = math::boxplus(math::quat_from_wxyz(x.segment<4>(a)), d);
        x.segment<4>(a) = math::quat_to_wxyz(q);
      }
      a += 4;
      t += 3;
    } else {
      const int n = sizes_[s];
      x.segment(a, n) += dx.segment(t, n);
      a += n;
      t += n;
    }
  }
}

void BlockLayout::boxminus(const Eigen::Ref<const Eigen::VectorXd>& x1, const Eigen::Ref<const Eigen::VectorXd>& x0,
                           Eigen::Ref<Eigen::VectorXd> dx) const {
  int a = 0;
  int t = 0;
  for (int s = 0; s < count_; ++s) {
    if (kinds_[s] == Kind::Quaternion) {
      dx.segment<3>(t) =
          math::boxminus(math::quat_from_wxyz(x1.segment<4>(a)), math::quat_from_wxyz(x0.segment<4>(a)));
      a += 4;
      t += 3;
    } else {
      const int n = sizes_[s];
      dx.segment(t, n) = x1.segment(a, n) - x0.segment(a, n);
      a += n;
      t += n;
    }
  }
}

std::string BlockLayout::describe() const {
  std::string out;
  for (int s = 0; s < count_; ++s) {
    if (!out.empty()) out.push_back(' ');
    if (kinds_[s] == Kind::Quaternion) {
      out.push_back('q');
    } else {
      out.push_back('e');
      out.append(std::to_string(sizes_[s]));
    }
  }
  return out;
}

bool BlockLayout::operator==(const BlockLayout& o) const {
  if (count_ != o.count_) return false;
  for (int s = 0; s < count_; ++s)
    if (kinds_[s] != o.kinds_[s] || sizes_[s] != o.sizes_[s]) return false;
  return true;
}

}  // namespace rtslam::filter
