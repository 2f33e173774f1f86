// World and renderer: exact geometry (markers project where the image shows them, 0.3 px), determinism,
// noise statistics, corner-rich textures, motion blur, ray casting, world configuration.
#include <cmath>
#include <cstring>
#include <numbers>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/sim/renderer.hpp"
#include "rtslam/sim/world.hpp"

namespace rtslam::sim {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
using Eigen::Vector3f;

// EuRoC cam0 (mav0/cam0/sensor.yaml): 752x480, pinhole + radial-tangential.
models::PinholeCamera euroc_cam0() {
  models::CameraIntrinsics in;
  in.width = 752;
  in.height = 480;
  in.fx = 458.654;
  in.fy = 457.296;
  in.cx = 367.215;
  in.cy = 248.375;
  in.model = models::DistortionModel::RadTan;
  in.coeffs = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  return models::PinholeCamera(in);
}

// A camera in the room looking roughly along +x, tilted and rolled a little (C: z forward, x right, y down).
math::Pose camera_pose(double yaw = 0.2, double pitch = 0.15, double roll = 0.1) {
  Eigen::Matrix3d R_WC0;  // columns: camera x -> -y_W, camera y -> -z_W, camera z -> +x_W
  R_WC0 << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(yaw, Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Vector3d::UnitY()) *
                             Eigen::AngleAxisd(roll, Vector3d::UnitX()))
                                .toRotationMatrix() *
                            R_WC0;
  math::Pose T;
  T.q = Eigen::Quaterniond(R);
  T.p = Vector3d(0.3, -0.2, 1.4);
  return T;
}

WorldConfig uniform_room(int grey) {
  WorldConfig c = WorldConfig::preset("room");
  c.texture = "uniform";
  c.uniform_grey = grey;
  return c;
}

TEST(Renderer, MarkersProjectWhereTheImageShowsThem) {
  const models::PinholeCamera cam = euroc_cam0();
  World world(uniform_room(40));
  const math::Pose T_WC = camera_pose();
  // Markers on whatever surface the rays of a grid of (sub-pixel) positions hit, including the strongly distorted
  // corners of the image; the disc radius is chosen to look ~3 px wide.
  std::vector<Vector3d> centers;
  Rng rng(5);
  for (int gy = 0; gy < 5; ++gy)
    for (int gx = 0; gx < 7; ++gx) {
      const Vector2d px(30.0 + gx * 115.0 + randu(rng, 0, 1), 25.0 + gy * 105.0 + randu(rng, 0, 1));
      Vector3d ray;
      ASSERT_TRUE(cam.unproject(px, ray));
      const Vector3d d_W = T_WC.q * ray;
      Hit hit;
      ASSERT_TRUE(world.cast(T_WC.p.cast<float>(), d_W.cast<float>(), hit));
      const Vector3d p_W = T_WC.p + static_cast<double>(hit.t) * d_W;
      const double radius = 3.0 * (p_W - T_WC.p).norm() / cam.intrinsics().fx;
      // Keep only markers whose disc lies whole on one visible face (not cut by an edge or an occluder): the
      // surroundings at 2 radii along the face's axes must be seen on the same face.
      const Face& face = world.faces()[static_cast<std::size_t>(hit.face)];
      bool whole = true;
      for (int axis : {(face.axis + 1) % 3, (face.axis + 2) % 3})
        for (double s : {-2.0, 2.0}) {
          Vector3d q = p_W;
          q[axis] += s * radius;
          Hit h;
          whole &= world.cast(T_WC.p.cast<float>(), (q - T_WC.p).cast<float>(), h) && h.face == hit.face &&
                   std::abs(h.t - 1.0f) < 1e-4f;
        }
      if (!whole) continue;
      centers.push_back(p_W);
      world.markers().push_back(Marker{p_W, radius, 255.0f});
    }
  RenderOptions opt;
  opt.supersampling = 3;
  opt.noise_std = 0.0;
  const Renderer renderer(world, cam, opt);
  const cv::Mat img = renderer.render(T_WC, 1);
  int checked = 0, distortion_matters = 0;
  double worst = 0.0;
  for (std::size_t k = 0; k < centers.size(); ++k) {
    Vector2d expected;
    ASSERT_TRUE(cam.project(T_WC.inverse_transform(centers[k]), expected));
    if (!cam.in_image(expected, 8.0)) continue;
    // Intensity-weighted centroid above the background in a window around the expected position.
    double sw = 0.0, su = 0.0, sv = 0.0;
    const int u0 = static_cast<int>(std::lround(expected.x())), v0 = static_cast<int>(std::lround(expected.y()));
    for (int v = v0 - 7; v <= v0 + 7; ++v)
      for (int u = u0 - 7; u <= u0 + 7; ++u) {
        const double w = std::max(0.0, img.at<std::uint8_t>(v, u) - 40.0);
        sw += w;
        su += w * u;
        sv += w * v;
      }
    ASSERT_GT(sw, 500.0) << "marker " << k << " not visible near " << expected.transpose();
    const double err = (Vector2d(su / sw, sv / sw) - expected).norm();
    worst = std::max(worst, err);
    if (std::getenv("RTSLAM_SIM_DEBUG")) std::printf("marker %zu at %.1f %.1f err %.3f (%.3f %.3f)\n", k, expected.x(), expected.y(), err, su / sw - expected.x(), sv / sw - expected.y());
    EXPECT_LT(err, 0.3) << "marker " << k << " at " << expected.transpose();
    ++checked;
    // Without the distortion the same point would be elsewhere: the check depends on the exact camera model.
    const Vector3d p_C = T_WC.inverse_transform(centers[k]);
    const auto& in = cam.intrinsics();
    const Vector2d pinhole(in.fx * p_C.x() / p_C.z() + in.cx, in.fy * p_C.y() / p_C.z() + in.cy);
    if ((pinhole - expected).norm() > 2.0) ++distortion_matters;
  }
  EXPECT_GE(checked, 28);
  EXPECT_GE(distortion_matters, 10);
  RecordProperty("worst_marker_error_px", std::to_string(worst));
}

TEST(Renderer, IsDeterministicAndIndependentOfTheThreadCount) {
  const models::PinholeCamera cam = euroc_cam0();
  WorldConfig c = WorldConfig::preset("small-room");
  c.texel_size = 0.01;
  const World world(c);
  RenderOptions one;
  one.threads = 1;
  one.supersampling = 1;
  RenderOptions two = one;
  two.threads = 2;
  const Renderer r1(world, cam, one), r2(world, cam, two);
  math::Pose T = camera_pose();
  T.p = Vector3d(0.1, 0.1, 1.3);
  const cv::Mat a = r1.render(T, 42), b = r2.render(T, 42), c2 = r2.render(T, 43);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, c2, cv::NORM_L1), 0.0);  // another seed, other noise
}

TEST(Renderer, PixelNoiseHasTheRequestedStandardDeviation) {
  const models::PinholeCamera cam = euroc_cam0();
  const World world(uniform_room(100));
  RenderOptions opt;
  opt.noise_std = 3.0;
  opt.supersampling = 1;
  const Renderer renderer(world, cam, opt);
  const cv::Mat img = renderer.render(camera_pose(), 9);
  cv::Scalar mean, stddev;
  cv::meanStdDev(img, mean, stddev);
  EXPECT_NEAR(mean[0], 100.0, 0.1);
  EXPECT_NEAR(stddev[0], 3.0, 0.1);  // rounding adds 1/12 grey level² of variance: sqrt(9 + 0.083) = 3.014
}

TEST(Renderer, ProceduralRoomIsRichInCornersEverywhere) {
  const models::PinholeCamera cam = euroc_cam0();
  const World world(WorldConfig::preset("room"));  // the real preset (5 mm texels)
  const Renderer renderer(world, cam, RenderOptions{});
  for (double yaw : {0.0, 3.1}) {
    const cv::Mat img = renderer.render(camera_pose(yaw, 0.1, 0.0), 3);
    std::vector<cv::Point2f> corners;
    cv::goodFeaturesToTrack(img, corners, 1000, 0.01, 8, cv::noArray(), 5, false);
    // Corners spread over the whole image: cells of a 6x4 grid that contain at least 3 corners.
    int cells[4][6] = {};
    for (const auto& p : corners) ++cells[std::min(3, static_cast<int>(p.y / 120))][std::min(5, static_cast<int>(p.x / 125.4))];
    int filled = 0;
    for (auto& row : cells)
      for (int n : row) filled += n >= 3 ? 1 : 0;
    EXPECT_GE(corners.size(), 300u) << "yaw " << yaw;
    EXPECT_GE(filled, 22) << "yaw " << yaw;
  }
}

TEST(Renderer, UniformWorldHasNoCorners) {
  // The corner check above can fail: a uniform world (apart from the room's edges) yields few corners.
  const models::PinholeCamera cam = euroc_cam0();
  const World world(uniform_room(128));
  RenderOptions opt;
  opt.noise_std = 0.0;
  opt.supersampling = 1;
  const Renderer renderer(world, cam, opt);
  const cv::Mat img = renderer.render(camera_pose(0.0, 0.0, 0.0), 3);
  std::vector<cv::Point2f> corners;
  cv::goodFeaturesToTrack(img, corners, 1000, 0.01, 8, cv::noArray(), 5, false);
  EXPECT_LT(corners.size(), 300u);
}

TEST(Renderer, MotionBlurSmoothsAFastRotation) {
  const models::PinholeCamera cam = euroc_cam0();
  WorldConfig c = WorldConfig::preset("room");
  c.texel_size = 0.015;
  const World world(c);
  RenderOptions sharp;
  sharp.noise_std = 0.0;
  RenderOptions blurred = sharp;
  blurred.motion_blur = true;
  blurred.exposure_s = 0.01;
  const Renderer rs(world, cam, sharp), rb(world, cam, blurred);
  ASSERT_EQ(rb.pose_count(), 4);
  // 400 deg/s yaw during a 10 ms exposure: about 25 px of smear at the centre.
  std::vector<math::Pose> poses;
  for (double dt : rb.pose_time_offsets()) poses.push_back(camera_pose(0.5 + 7.0 * dt, 0.1, 0.0));
  const cv::Mat a = rs.render(camera_pose(0.5, 0.1, 0.0), 1), b = rb.render(poses, 1);
  cv::Mat ga, gb;
  cv::Sobel(a, ga, CV_32F, 1, 0);
  cv::Sobel(b, gb, CV_32F, 1, 0);
  EXPECT_LT(cv::norm(gb, cv::NORM_L2), 0.8 * cv::norm(ga, cv::NORM_L2));
  // Without motion the blurred renderer gives the sharp image (same sub-pixel rays, same instant).
  const cv::Mat b0 = rb.render(camera_pose(0.5, 0.1, 0.0), 1);
  EXPECT_EQ(cv::norm(a, b0, cv::NORM_INF), 0.0);
}

TEST(Renderer, CullingGivesThePictureOfCastingAgainstEveryObstacle) {
  // The renderer tests each tile's rays only against the obstacles projected onto it; a brute-force render
  // (every obstacle, every pixel) must give the same bytes, including next to obstacles that cross the camera
  // plane and with obstacles partly outside the image.
  const models::PinholeCamera cam = euroc_cam0();
  WorldConfig c = WorldConfig::preset("hall");  // pillars and random boxes
  c.texel_size = 0.02;
  const World world(c);
  RenderOptions opt;
  opt.supersampling = 1;
  opt.noise_std = 0.0;
  const Renderer renderer(world, cam, opt);
  std::vector<math::Pose> poses;
  for (double yaw : {0.0, 1.3, 2.6, 3.9, 5.2}) {
    math::Pose T = camera_pose(yaw, 0.2, 0.1);
    T.p = Vector3d(0.5, -0.3, 1.2);
    poses.push_back(T);
  }
  // Close to obstacles: 0.2 m in front of a face, looking 60 degrees away from its normal, so that the box spans
  // the camera plane and is seen at the edge of the image.
  for (std::size_t k = 0; k < world.boxes().size() && poses.size() < 15; ++k) {
    const Aabb& b = world.boxes()[k];
    const Vector3d centre = 0.5 * (b.lo + b.hi).cast<double>();
    for (double yaw : {-1.05, 1.05}) {
      math::Pose T = camera_pose(std::numbers::pi + yaw, 0.1, 0.0);  // yaw 0 would look along -x
      T.p = Vector3d(b.hi.x() + 0.2, centre.y(), std::min(1.2, 0.8 * b.hi.z()));
      if (world.is_free(T.p, 0.05)) poses.push_back(T);
    }
  }
  ASSERT_GE(poses.size(), 10u);
  for (std::size_t n = 0; n < poses.size(); ++n) {
    const math::Pose& T = poses[n];
    const cv::Mat img = renderer.render(T, 1);
    const Eigen::Matrix3f R_WC = T.q.toRotationMatrix().cast<float>();
    const Vector3f p_WC = T.p.cast<float>();
    int differ = 0;
    for (int v = 0; v < img.rows; ++v)
      for (int u = 0; u < img.cols; ++u) {
        Vector3d ray;
        float grey = 0.0f;
        Hit hit;
        if (cam.unproject(Vector2d(u, v), ray)) {
          const Vector3f d = R_WC * ray.cast<float>();
          if (world.cast(p_WC, d, hit)) grey = world.shade(hit.face, p_WC + hit.t * d);
        }
        differ += img.at<std::uint8_t>(v, u) == static_cast<std::uint8_t>(std::lround(std::clamp(grey, 0.0f, 255.0f)))
                      ? 0
                      : 1;
      }
    EXPECT_EQ(differ, 0) << "pose " << n;
  }
}

TEST(World, TracesTheSameGreyLevelsEightRaysAtATimeAsOneAtATime) {
  // World::trace's AVX2 path (eight rays per step) against its plain path: the same float, bit for bit, for rays
  // from many origins in a room with pillars and boxes, some with zero direction components (the plain slab test
  // of parallel rays), some from origins on the planes of the boxes' faces (a distance of exactly 0: near ties of
  // the slab test) and with tiny or subnormal direction components (1/d infinite, 0 · ∞ = NaN: the comparisons'
  // NaN semantics), narrow bundles whose packets see one face, and a ray count that is not a multiple of eight.
  WorldConfig c = WorldConfig::preset("hall");
  c.texel_size = 0.02;
  World world(c);
  if (!world.vectorized()) GTEST_SKIP() << "no AVX2 on this CPU: trace has only its plain path";
  std::mt19937_64 rng(7);
  std::vector<Vector3f> o, d;
  std::vector<int> all(world.boxes().size());
  for (std::size_t k = 0; k < all.size(); ++k) all[k] = static_cast<int>(k);
  const Vector3d lo = world.room_min(), hi = world.room_max();
  while (o.size() < 40003) {
    Vector3d p;
    for (int i = 0; i < 3; ++i) p[i] = randu(rng, lo[i], hi[i]);
    if (!world.is_free(p, 0.01)) continue;
    for (int k = 0; k < 64; ++k) {
      Vector3f dir;
      for (int i = 0; i < 3; ++i) dir[i] = static_cast<float>(randn(rng));
      Vector3f origin = p.cast<float>();
      if (k % 16 == 3) dir[k % 3] = 0.0f;  // parallel to a face
      if (k % 32 == 5) dir[(k + 1) % 3] = -0.0f;
      if (k % 8 == 6) dir[k % 3] = k % 16 == 6 ? 1e-40f : -1e-30f;  // subnormal, tiny
      if (k % 4 == 1) {  // on the plane of a face of some box, some going along it (0 · ∞ on that axis)
        const Aabb& b = world.boxes()[static_cast<std::size_t>(k / 4) % world.boxes().size()];
        origin[k % 3] = k % 8 == 1 ? b.lo[k % 3] : b.hi[k % 3];
        if (k % 16 == 1 || k % 16 == 5) dir[k % 3] = -1e-40f;  // lo plane: NaN far distance; hi: near
        if (k % 16 == 9 || k % 16 == 13) dir[k % 3] = 1e-40f;  // lo plane: NaN near distance; hi: far
      }
      o.push_back(origin);
      d.push_back(dir);
    }
    // A narrow bundle, like a tile's rays: eight consecutive rays mostly on one face (the vector shading).
    Vector3f axis;
    for (int i = 0; i < 3; ++i) axis[i] = static_cast<float>(randn(rng));
    for (int k = 0; k < 64; ++k) {
      Vector3f dir = axis;
      for (int i = 0; i < 3; ++i) dir[i] += static_cast<float>(0.002 * randn(rng));
      o.push_back(p.cast<float>());
      d.push_back(dir);
    }
  }
  o.resize(40003);
  d.resize(40003);
  std::vector<float> columns[6];
  for (std::size_t k = 0; k < o.size(); ++k)
    for (int i = 0; i < 3; ++i) {
      columns[i].push_back(o[k][i]);
      columns[3 + i].push_back(d[k][i]);
    }
  const World::Rays rays{{columns[0].data(), columns[1].data(), columns[2].data()},
                         {columns[3].data(), columns[4].data(), columns[5].data()},
                         o.size()};
  std::vector<float> plain(o.size()), packed(o.size());
  world.set_vectorized(false);
  world.trace(rays, all, plain.data());
  world.set_vectorized(true);
  world.trace(rays, all, packed.data());
  int differ = 0, lit = 0, on_obstacles = 0;
  for (std::size_t k = 0; k < o.size(); ++k) {
    differ += std::memcmp(&plain[k], &packed[k], sizeof(float)) == 0 ? 0 : 1;
    lit += plain[k] > 0.0f ? 1 : 0;
    Hit hit;
    on_obstacles += world.cast(o[k], d[k], hit) && hit.face >= 6 ? 1 : 0;  // faces 0-5: the room
  }
  EXPECT_EQ(differ, 0);
  EXPECT_GT(lit, 38000);
  EXPECT_GT(on_obstacles, 2000);  // the slab test of the boxes is exercised, not only the room's
  // Outside the room nothing is hit: 0 on both paths.
  const std::vector<float> far(16, 1e3f), dx(16, 1.0f), dy(16, 0.5f), dz(16, 0.25f);
  std::vector<float> grey(16, 1.0f);
  world.trace(World::Rays{{far.data(), far.data(), far.data()}, {dx.data(), dy.data(), dz.data()}, 16}, all,
              grey.data());
  for (float g : grey) EXPECT_EQ(g, 0.0f);
}

TEST(Renderer, GivesTheSameImagesWithAndWithoutItsVectorizedPaths) {
  // The AVX2 paths (rays rotated and traced eight at a time, sub-samples averaged and pixels rounded eight at a
  // time) against the plain ones, byte for byte: one pose per image (the rotation's vector path) and motion blur
  // (one pose per sub-sample), 1 and 2x2 sub-samples, and an image whose width and height are not multiples of 8
  // (partial tiles, the vector loops' scalar tails).
  models::CameraIntrinsics cropped = euroc_cam0().intrinsics();
  cropped.width = 747;
  cropped.height = 477;
  WorldConfig c = WorldConfig::preset("room");
  c.texel_size = 0.01;
  World world(c);
  if (!world.vectorized()) GTEST_SKIP() << "no AVX2 on this CPU: the renderer has only its plain paths";
  for (const models::PinholeCamera& cam : {euroc_cam0(), models::PinholeCamera(cropped)}) {
    for (const bool blur : {false, true}) {
      for (const int n : {1, 2}) {
        RenderOptions opt;
        opt.motion_blur = blur;
        opt.supersampling = n;
        const Renderer renderer(world, cam, opt);
        for (double yaw : {0.0, 2.0, 4.0}) {
          std::vector<math::Pose> poses;
          for (int k = 0; k < renderer.pose_count(); ++k) {
            math::Pose T = camera_pose(yaw + 0.01 * k, 0.15, 0.1);
            T.p = Vector3d(0.3 + 0.002 * k, -0.2, 1.4);
            poses.push_back(T);
          }
          world.set_vectorized(false);
          const cv::Mat plain = renderer.render(poses, 5);
          world.set_vectorized(true);
          const cv::Mat packed = renderer.render(poses, 5);
          EXPECT_EQ(cv::norm(plain, packed, cv::NORM_INF), 0.0)
              << cam.intrinsics().width << " px wide, blur " << blur << ", n " << n << ", yaw " << yaw;
        }
      }
    }
  }
}

TEST(World, CastsRaysToTheClosestFace) {
  WorldConfig c;
  c.room_size = Vector3d(8, 6, 3);
  c.texture = "uniform";
  c.boxes = {{Eigen::Vector2d(2.0, 0.0), Vector3d(0.5, 0.5, 1.0)}};
  const World world(c);
  Hit hit;
  // Towards +y: the wall at y = 3.
  ASSERT_TRUE(world.cast(Vector3f(0, 0, 0.5), Vector3f(0, 1, 0), hit));
  EXPECT_NEAR(hit.t, 3.0f, 1e-5f);
  EXPECT_EQ(world.faces()[static_cast<std::size_t>(hit.face)].axis, 1);
  // Towards +x at box height: the box face at x = 1.75, not the wall at x = 4.
  ASSERT_TRUE(world.cast(Vector3f(0, 0, 0.5), Vector3f(2, 0, 0), hit));
  EXPECT_NEAR(hit.t, 0.875f, 1e-5f);
  EXPECT_NEAR(world.faces()[static_cast<std::size_t>(hit.face)].coord, 1.75f, 1e-6f);
  // Above the box: the wall.
  ASSERT_TRUE(world.cast(Vector3f(0, 0, 1.5), Vector3f(1, 0, 0), hit));
  EXPECT_NEAR(hit.t, 4.0f, 1e-5f);
  // Down: the floor.
  ASSERT_TRUE(world.cast(Vector3f(0, 0, 1.5), Vector3f(0, 0, -1), hit));
  EXPECT_NEAR(hit.t, 1.5f, 1e-5f);
  EXPECT_TRUE(world.is_free(Vector3d(0, 0, 1.5)));
  EXPECT_FALSE(world.is_free(Vector3d(2.0, 0.0, 0.5)));
  EXPECT_FALSE(world.is_free(Vector3d(5.0, 0.0, 0.5)));
}

TEST(World, ReadsYamlStrictlyAndValidates) {
  const std::string ok = R"(
seed: 4
room: {size: [6, 5, 2.5]}
texel_size: 0.01
boxes: [{center: [1.5, 1.0], size: [0.5, 0.5, 0.8]}]
pillars: [{center: [-1.0, 1.0], size: [0.3, 0.3]}]
random_boxes: 2
)";
  YamlMap m(YAML::Load(ok), "test.yaml");
  const WorldConfig c = WorldConfig::from_yaml(m);
  EXPECT_EQ(c.seed, 4u);
  EXPECT_DOUBLE_EQ(c.room_size.z(), 2.5);
  ASSERT_EQ(c.boxes.size(), 1u);
  ASSERT_EQ(c.pillars.size(), 1u);
  YamlMap bad_key(YAML::Load("room: {size: [6, 5, 2.5]}\ncolour: red\n"), "test.yaml");
  EXPECT_THROW(WorldConfig::from_yaml(bad_key), ConfigError);
  YamlMap outside(YAML::Load("boxes: [{center: [3.9, 0], size: [0.5, 0.5, 0.5]}]\n"), "test.yaml");
  EXPECT_THROW(WorldConfig::from_yaml(outside), ConfigError);
  EXPECT_THROW(WorldConfig::preset("castle"), ConfigError);
  for (const std::string& name : WorldConfig::preset_names()) EXPECT_NO_THROW(WorldConfig::preset(name).validate(name));
}

}  // namespace
}  // namespace rtslam::sim
