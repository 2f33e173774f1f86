#include <gtest/gtest.h>

#include "rtslam/core/error.hpp"
#include "rtslam/vision/image.hpp"

using namespace rtslam::vision;

TEST(Image, RoiViewAddressesTheParentPixels) {
  Image img(10, 7);
  for (int v = 0; v < 7; ++v)
    for (int u = 0; u < 10; ++u) img.at(u, v) = static_cast<std::uint8_t>(10 * v + u);
  const ImageView sub = img.roi(3, 2, 4, 5);
  EXPECT_EQ(sub.width, 4);
  EXPECT_EQ(sub.height, 5);
  EXPECT_EQ(sub.stride, 10);
  EXPECT_EQ(sub.at(0, 0), 23);
  EXPECT_EQ(sub.at(3, 4), 66);
  const ImageView subsub = sub.roi(1, 1, 2, 2);
  EXPECT_EQ(subsub.at(1, 1), img.at(5, 4));
}

TEST(Image, RoiOutsideTheViewThrows) {
  Image img(10, 7);
  EXPECT_THROW(img.roi(8, 0, 3, 2), rtslam::InvariantError);
  EXPECT_THROW(img.roi(-1, 0, 3, 2), rtslam::InvariantError);
  EXPECT_NO_THROW(img.roi(0, 0, 10, 7));
}

TEST(Image, CopyOfAStridedViewIsContiguous) {
  Image img(6, 4, 9);
  img.at(2, 1) = 200;
  const Image copy = Image::copy_of(img.roi(1, 1, 3, 2));
  EXPECT_EQ(copy.width(), 3);
  EXPECT_EQ(copy.view().stride, 3);
  EXPECT_EQ(copy.at(1, 0), 200);
  EXPECT_EQ(copy.at(0, 1), 9);
}

TEST(Roi, IntersectionClipsAndCanBeEmpty) {
  const Roi a{0, 0, 10, 10};
  EXPECT_EQ(a.intersect(Roi{5, -3, 10, 6}), (Roi{5, 0, 5, 3}));
  EXPECT_TRUE(a.intersect(Roi{12, 0, 3, 3}).empty());
  EXPECT_TRUE(a.contains(9, 9));
  EXPECT_FALSE(a.contains(10, 9));
}
