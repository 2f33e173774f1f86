#include "rtslam/io/trajectory_io.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <filesystem>

#include <sys/stat.h>

#include "io_test_util.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/io/text.hpp"

namespace rtslam::io {
namespace {

using test::TempDir;
using test::write_text;

bool bits_equal(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

Trajectory random_trajectory(Rng& rng, size_t n, bool full) {
  Trajectory traj;
  TimeNs t = 1403715273262142976;
  for (size_t i = 0; i < n; ++i) {
    StampedPose p;
    t += 4'999'999 + static_cast<TimeNs>(randu(rng, 0.0, 100.0));
    p.t = t;
    p.p_WR = randn_vec<3>(rng, 10.0);
    p.q_WR = Eigen::Quaterniond(Eigen::Vector4d(randn_vec<4>(rng))).normalized();
    if (full) {
      p.v_WR = randn_vec<3>(rng);
      p.gyro_bias = randn_vec<3>(rng, 1e-3);
      p.accel_bias = randn_vec<3>(rng, 1e-2);
      const Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::NullaryExpr([&] { return randn(rng); });
      p.cov = A * A.transpose() * 1e-4;
    }
    traj.poses.push_back(p);
  }
  return traj;
}

void expect_bit_identical(const Eigen::Ref<const Eigen::MatrixXd>& a, const Eigen::Ref<const Eigen::MatrixXd>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (Eigen::Index i = 0; i < a.size(); ++i) EXPECT_TRUE(bits_equal(a.data()[i], b.data()[i])) << i;
}

void expect_same_pose(const StampedPose& a, const StampedPose& b) {
  EXPECT_EQ(a.t, b.t);
  expect_bit_identical(a.p_WR, b.p_WR);
  expect_bit_identical(a.q_WR.coeffs(), b.q_WR.coeffs());
  ASSERT_EQ(a.v_WR.has_value(), b.v_WR.has_value());
  if (a.v_WR) expect_bit_identical(*a.v_WR, *b.v_WR);
  ASSERT_EQ(a.gyro_bias.has_value(), b.gyro_bias.has_value());
  if (a.gyro_bias) expect_bit_identical(*a.gyro_bias, *b.gyro_bias);
  ASSERT_EQ(a.accel_bias.has_value(), b.accel_bias.has_value());
  if (a.accel_bias) expect_bit_identical(*a.accel_bias, *b.accel_bias);
  ASSERT_EQ(a.cov.has_value(), b.cov.has_value());
  if (a.cov) expect_bit_identical(*a.cov, *b.cov);
}

TEST(Text, SecondsParseExactlyToNanoseconds) {
  TimeNs t = 0;
  ASSERT_TRUE(parse_seconds("1403715273.262142976", t));
  EXPECT_EQ(t, 1403715273262142976);
  ASSERT_TRUE(parse_seconds("1403715273.26214", t));
  EXPECT_EQ(t, 1403715273262140000);
  ASSERT_TRUE(parse_seconds("-0.5", t));
  EXPECT_EQ(t, -500'000'000);
  ASSERT_TRUE(parse_seconds("0.0000000015", t));  // rounds the 10th decimal
  EXPECT_EQ(t, 2);
  ASSERT_TRUE(parse_seconds("1.5e3", t));
  EXPECT_EQ(t, 1'500'000'000'000);
  EXPECT_FALSE(parse_seconds("12a", t));
  EXPECT_FALSE(parse_seconds("", t));
  EXPECT_FALSE(parse_seconds(".", t));
  EXPECT_EQ(format_seconds(1403715273262142976), "1403715273.262142976");
  EXPECT_EQ(format_seconds(-1), "-0.000000001");
}

TEST(Text, DoubleFormatRoundTripsEveryBit) {
  Rng rng(7);
  for (int i = 0; i < 1000; ++i) {
    const double x = randn(rng) * std::pow(10.0, randu(rng, -300, 300));
    double y = 0;
    ASSERT_TRUE(parse_double(format_double(x), y));
    EXPECT_TRUE(bits_equal(x, y)) << format_double(x);
  }
}

TEST(Text, LineReaderRefusesAPipeInsteadOfBlocking) {
  // Review 27 Nov: the stream was opened before the path was checked, and opening a FIFO with no writer blocks.
  TempDir dir;
  const std::string fifo = dir / "pipe.csv";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_THROW_WITH(LineReader{fifo}, IoError, "pipe.csv: not a regular file (a directory, pipe or device)");
  EXPECT_THROW_WITH(LineReader{dir / "absent.csv"}, IoError, "absent.csv: file not found");
}

TEST(Text, LineReaderDropsAByteOrderMarkAndCarriageReturns) {
  // A data.csv saved by a Windows editor: "\xEF\xBB\xBF#timestamp [ns],filename\r\n..." made line 1 malformed.
  TempDir dir;
  write_text(dir / "data.csv", "\xEF\xBB\xBF#timestamp [ns],filename\r\n1,a.png\r\n\xEF\xBB\xBF"
                                  "2,b.png\n");
  LineReader in(dir / "data.csv");
  std::string line;
  ASSERT_TRUE(in.next(line));
  EXPECT_EQ(line, "#timestamp [ns],filename");
  ASSERT_TRUE(in.next(line));
  EXPECT_EQ(line, "1,a.png");
  ASSERT_TRUE(in.next(line));
  EXPECT_EQ(line, "\xEF\xBB\xBF" "2,b.png");  // only the file's first bytes are a byte-order mark
}

TEST(Text, DoubleOutOfRangeIsRefusedNotZero) {
  // Review 27 Nov: from_chars leaves its output unset out of range, and "1e400" was read as the caller's 0.
  double y = 42.0;
  EXPECT_FALSE(parse_double("1e400", y));
  EXPECT_FALSE(parse_double("-2e308", y));
  EXPECT_EQ(y, 42.0);
  ASSERT_TRUE(parse_double("1e-400", y));  // below the subnormals: zero, as any reader would round it
  EXPECT_EQ(y, 0.0);
  ASSERT_TRUE(parse_double("-1e-400", y));
  EXPECT_TRUE(y == 0.0 && std::signbit(y));
  ASSERT_TRUE(parse_double("1e-310", y));  // subnormal
  EXPECT_EQ(y, 1e-310);
  ASSERT_TRUE(parse_double("1.7976931348623157e308", y));
  EXPECT_EQ(y, std::numeric_limits<double>::max());
  EXPECT_FALSE(parse_double("1e400x", y));
}

TEST(TrajectoryIo, TumRoundTripIsBitIdenticalWithEightColumns) {
  TempDir dir;
  Rng rng(42);
  const Trajectory traj = random_trajectory(rng, 200, false);
  write_tum(dir / "t.txt", traj);
  // evo-style check: every non-comment line has exactly 8 columns, and there is at most one comment line.
  LineReader in(dir / "t.txt");
  std::string line;
  int comments = 0;
  int rows = 0;
  while (in.next(line)) {
    if (line.rfind("#", 0) == 0) {
      ++comments;
      continue;
    }
    EXPECT_EQ(split(line, ' ').size(), 8u) << line;
    ++rows;
  }
  EXPECT_LE(comments, 1);
  EXPECT_EQ(rows, 200);
  EXPECT_EQ(detect_trajectory_format(dir / "t.txt"), TrajectoryFormat::Tum);
  const Trajectory back = read_trajectory(dir / "t.txt");
  ASSERT_EQ(back.poses.size(), traj.poses.size());
  EXPECT_TRUE(back.has_timestamps);
  for (size_t i = 0; i < traj.poses.size(); ++i) expect_same_pose(traj.poses[i], back.poses[i]);
}

TEST(TrajectoryIo, TrajectoryCsvRoundTripIsBitIdenticalWithAllGroups) {
  TempDir dir;
  Rng rng(43);
  const Trajectory traj = random_trajectory(rng, 100, true);
  write_trajectory_csv(dir / "trajectory.csv", traj);
  const std::string text = test::read_text(dir / "trajectory.csv");
  EXPECT_NE(text.find("right perturbation"), std::string::npos);  // the convention is stated
  EXPECT_NE(text.find("#timestamp [ns], p_RS_R_x [m]"), std::string::npos);
  EXPECT_NE(text.find(", b_w_RS_S_x [rad s^-1]"), std::string::npos);
  EXPECT_LT(text.find("b_w_RS_S_x"), text.find("b_a_RS_S_x"));  // gyro bias before accel bias, as EuRoC
  EXPECT_NE(text.find(", cov_55\n"), std::string::npos);
  const Trajectory back = read_trajectory(dir / "trajectory.csv");
  ASSERT_EQ(back.poses.size(), traj.poses.size());
  for (size_t i = 0; i < traj.poses.size(); ++i) expect_same_pose(traj.poses[i], back.poses[i]);
}

TEST(TrajectoryIo, TrajectoryCsvRoundTripWithCovarianceOnly) {
  TempDir dir;
  Rng rng(44);
  Trajectory traj = random_trajectory(rng, 20, true);
  for (auto& p : traj.poses) {
    p.v_WR.reset();
    p.gyro_bias.reset();
    p.accel_bias.reset();
  }
  write_trajectory_csv(dir / "trajectory.csv", traj);
  const Trajectory back = read_trajectory(dir / "trajectory.csv");
  ASSERT_EQ(back.poses.size(), 20u);
  for (size_t i = 0; i < traj.poses.size(); ++i) expect_same_pose(traj.poses[i], back.poses[i]);
}

TEST(TrajectoryIo, WriterRejectsMixedOptionalFields) {
  TempDir dir;
  Rng rng(45);
  Trajectory traj = random_trajectory(rng, 3, true);
  traj.poses[2].cov.reset();
  EXPECT_THROW_WITH(write_trajectory_csv(dir / "x.csv", traj), DataError, "pose 2");
}

TEST(TrajectoryIo, KittiRoundTripHasNoTimestamps) {
  TempDir dir;
  Rng rng(46);
  const Trajectory traj = random_trajectory(rng, 10, false);
  write_kitti(dir / "00.txt", traj);
  EXPECT_EQ(detect_trajectory_format(dir / "00.txt"), TrajectoryFormat::Kitti);
  const Trajectory back = read_trajectory(dir / "00.txt");
  ASSERT_EQ(back.poses.size(), 10u);
  EXPECT_FALSE(back.has_timestamps);
  for (size_t i = 0; i < 10; ++i) {
    EXPECT_EQ(back.poses[i].t, static_cast<TimeNs>(i));
    EXPECT_LT((back.poses[i].p_WR - traj.poses[i].p_WR).norm(), 1e-12);
    EXPECT_LT(back.poses[i].q_WR.angularDistance(traj.poses[i].q_WR), 1e-9);
  }
}

TEST(TrajectoryIo, ReadsEurocGroundTruthOfV101) {
  const std::string path = test::euroc_dir() + "/mav0/state_groundtruth_estimate0/data.csv";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "dataset euroc-v101-static not found";
  const Trajectory gt = read_trajectory(path);
  ASSERT_EQ(gt.poses.size(), 2895u);
  const auto& p0 = gt.poses.front();
  EXPECT_EQ(p0.t, 1403715273262142976);
  EXPECT_DOUBLE_EQ(p0.p_WR.x(), 0.878895);
  EXPECT_DOUBLE_EQ(p0.q_WR.w(), 0.069433);
  EXPECT_DOUBLE_EQ(p0.q_WR.x(), -0.824237);
  ASSERT_TRUE(p0.v_WR && p0.gyro_bias && p0.accel_bias);
  EXPECT_DOUBLE_EQ(p0.gyro_bias->x(), -0.00224703);  // bwx comes before bax
  EXPECT_DOUBLE_EQ(p0.accel_bias->x(), -0.0180115);
  EXPECT_FALSE(p0.cov.has_value());
  // The TUM copy of the same poses agrees (its times are rounded to 10 us).
  const std::string tum = test::euroc_dir() + "/groundtruth/V1_01_easy_body.txt";
  const Trajectory body = read_trajectory(tum);
  ASSERT_FALSE(body.poses.empty());
  EXPECT_NEAR(static_cast<double>(body.poses[0].t - p0.t), 0.0, 1e4);
  EXPECT_NEAR((body.poses[0].p_WR - p0.p_WR).norm(), 0.0, 1e-5);
}

TEST(TrajectoryIo, ReadsOriginalAndHeaderlessEurocVariants) {
  TempDir dir;
  const std::string row = "1403715273262142976,0.878895,2.1834,0.948427,0.069433,-0.824237,-0.106942,-0.551702";
  write_text(dir / "orig.csv",
             "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], "
             "v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], b_w_RS_S_y [rad s^-1], "
             "b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], b_a_RS_S_z [m s^-2]\n" +
                 row + ",1,2,3,4,5,6,7,8,9\n");
  write_text(dir / "bare.csv", row + "\r\n" + "1403715273312143104,0,0,0,1,0,0,0\r\n");
  const Trajectory a = read_trajectory(dir / "orig.csv");
  ASSERT_EQ(a.poses.size(), 1u);
  EXPECT_DOUBLE_EQ(a.poses[0].v_WR->z(), 3.0);
  EXPECT_DOUBLE_EQ(a.poses[0].gyro_bias->x(), 4.0);
  EXPECT_DOUBLE_EQ(a.poses[0].accel_bias->z(), 9.0);
  const Trajectory b = read_trajectory(dir / "bare.csv");
  ASSERT_EQ(b.poses.size(), 2u);
  EXPECT_FALSE(b.poses[0].v_WR.has_value());
  EXPECT_EQ(b.poses[1].t, 1403715273312143104);
}

TEST(TrajectoryIo, ErrorsNameFileAndLine) {
  TempDir dir;
  write_text(dir / "back.txt", "# c\n1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0 1\n1.5 0 0 0 0 0 0 1\n");
  EXPECT_THROW_WITH(read_trajectory(dir / "back.txt"), DataError, "back.txt:4: timestamp");
  write_text(dir / "dup.txt", "1.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n");
  EXPECT_THROW_WITH(read_trajectory(dir / "dup.txt"), DataError, "duplicate");
  write_text(dir / "cols.txt", "1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n");
  EXPECT_THROW_WITH(read_trajectory(dir / "cols.txt", TrajectoryFormat::Tum), IoError, "cols.txt:2: expected 8");
  write_text(dir / "nan.csv", "1,0,0,0,1,0,0,0\n2,nan,0,0,1,0,0,0\n");
  EXPECT_THROW_WITH(read_trajectory(dir / "nan.csv"), DataError, "nan.csv:2: non-finite");
  write_text(dir / "word.csv", "1,0,0,0,1,0,0,0\n2,zero,0,0,1,0,0,0\n");
  EXPECT_THROW_WITH(read_trajectory(dir / "word.csv"), IoError, "word.csv:2: field 2 'zero'");
  write_text(dir / "q.txt", "1.0 0 0 0 0 0 0 2\n");
  EXPECT_THROW_WITH(read_trajectory(dir / "q.txt"), DataError, "q.txt:1: quaternion norm");
  write_text(dir / "rot.txt", "2 0 0 0 0 1 0 0 0 0 1 0\n");
  EXPECT_THROW_WITH(read_trajectory(dir / "rot.txt"), DataError, "rot.txt:1: rotation is not orthonormal");
  write_text(dir / "five.txt", "1 2 3 4 5\n");
  EXPECT_THROW_WITH(read_trajectory(dir / "five.txt"), IoError, "cannot tell the trajectory format");
  EXPECT_THROW_WITH(read_trajectory(dir / "missing.txt"), IoError, "missing.txt: file not found");
  // A TUM file with nanosecond stamps (ORB-SLAM's on EuRoC) says so instead of "not a number".
  write_text(dir / "ns.txt", "1403636579763555584 0 0 0 0 0 0 1\n");
  EXPECT_THROW_WITH(read_trajectory(dir / "ns.txt", TrajectoryFormat::Tum), IoError,
                    "ns.txt:1: timestamp '1403636579763555584' is not in seconds (a 19-digit integer: nanoseconds?); a "
                    "TUM trajectory holds seconds, e.g. 1403636579.763555584");
  // KITTI lines have no time field: the numbers are fields 1 to 12.
  write_text(dir / "kitti_nan.txt", "nan 0 0 0 0 1 0 0 0 0 1 0\n");
  EXPECT_THROW_WITH(read_trajectory(dir / "kitti_nan.txt", TrajectoryFormat::Kitti), DataError,
                    "kitti_nan.txt:1: non-finite value in field 1");
}

}  // namespace
}  // namespace rtslam::io
