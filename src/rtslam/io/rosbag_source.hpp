#pragma once
// ROS1 bags: reading one as a Dataset (the `rosbag:` kind of open_dataset) and writing a measurement stream into
// one (the simulator's sequences, any dataset). No ROS type appears here: the implementation is the only
// translation unit of io that includes ROS headers (compiled as C++17, see cmake/RtslamRos.cmake), and builds
// without ROS get stubs that throw ConfigError. docs/ros.md has the user's side.
//
// Reading (open_rosbag):
//  - Topics: one image topic per streamed camera (DatasetOptions::image_topics, default /camN/image_raw for each N of
//    DatasetOptions::cameras) of type sensor_msgs/Image or sensor_msgs/CompressedImage, and one IMU topic
//    (DatasetOptions::imu_topic, default /imu0; read when DatasetOptions::use_imu) of type sensor_msgs/Imu. A
//    missing image topic is an IoError that lists the bag's topics; a missing IMU topic is a warning (no IMU stream).
//  - Time: the messages' header stamps (default), or the bag's receive times (DatasetOptions::bag_receive_time).
//  - Order and checks: the bag is indexed when it is opened. Per topic, in the bag's order (its receive times),
//    stamps must increase strictly (backwards and duplicate stamps), IMU values must be finite, IMU dropouts longer
//    than max_imu_dropout samples are reported (the rate from the calibration, else the median interval), and raw
//    images must have a supported encoding, a consistent buffer and the calibration's size; compressed images are
//    decoded, and checked, when the stream reaches them. The policy is DatasetOptions::bad_input, as for every reader
//    (source.hpp): stop with an error naming the bag, topic, message index and stamp, or skip and count in
//    SourceStats. The streams are then merged by time, IMU first at equal times, then by camera.
//  - Images become 8-bit grey (grey_from_ros_image).
//  - Calibration: DatasetOptions::calibration, a file (anything load_calibration reads: rtslam rig YAML, Kalibr
//    camchain, EuRoC sensor.yaml, ...) or an EuRoC/ASL folder (PATH or PATH/mav0 with camN/sensor.yaml and
//    imu0/sensor.yaml); else, next to the bag, FILE.yaml (what write_rosbag writes), calibration.yaml,
//    camchain.yaml, sensor.yaml, or an EuRoC folder FILE/mav0 or mav0. Ground truth: the EuRoC folder's
//    state_groundtruth_estimate0/data.csv when the calibration came from one.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "rtslam/io/calibration.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/io/source.hpp"

namespace rtslam::io {

/// True when this build reads and writes ROS bags (CMake found ROS1, RTSLAM_WITH_ROS).
bool rosbag_supported();

/// Opens a bag (see the header comment). Throws IoError (file, topics), ConfigError (options, calibration) or
/// DataError (bad values under the Error policy), naming the bag and the problem; ConfigError in builds without ROS.
Dataset open_rosbag(const std::string& path, const DatasetOptions& options = {});

/// The rig of a calibration path: an EuRoC/ASL folder (PATH or PATH/mav0: camN/sensor.yaml for each N of
/// `cameras`, imu0/sensor.yaml when present; T_RS = T_BI⁻¹ T_BS with the IMU as R; TUM-VI's export: its dso/
/// Kalibr files, load_euroc_folder_calibration) or a calibration file
/// (load_calibration; its cameras `cameras` are kept, in that order). Throws ConfigError/IoError naming the path.
Rig load_rig(const std::string& path, const std::vector<int>& cameras = {0});

/// 8-bit grey pixels of a raw sensor_msgs/Image: mono8 / 8UC1 as they are, rgb8 / bgr8 / rgba8 / bgra8 (and their
/// 8UC3 / 8UC4 aliases, taken as BGR) with OpenCV's weights, bayer_{rggb,bggr,gbrg,grbg}8 demosaiced. Other
/// encodings (16-bit, float, YUV, ...) are refused. Returns an empty Mat and sets `error` (one line) when the
/// encoding is refused or `step` / `size` do not fit width x height; never throws.
cv::Mat grey_from_ros_image(const std::string& encoding, std::uint32_t width, std::uint32_t height, std::uint32_t step,
                            const std::uint8_t* data, std::size_t size, std::string* error);

/// The encodings grey_from_ros_image accepts, for messages ("mono8, 8UC1, rgb8, ...").
std::string supported_ros_image_encodings();

struct RosbagWriteOptions {
  std::vector<std::string> image_topics;  // topic of camera i of the rig (empty: /cam<i>/image_raw)
  std::string imu_topic = "/imu0";
  std::vector<std::string> camera_frames;  // header.frame_id of camera i (empty: the rig's camera names)
  std::string imu_frame = "imu0";
  std::string compression = "none";  // chunk compression: none | lz4 | bz2
  bool write_calibration = true;     // the rig as rtslam rig YAML in FILE.yaml (FILE.bag minus .bag), which
                                     // open_rosbag finds by itself
};

struct RosbagWriteStats {
  std::size_t images = 0;
  std::size_t imu_samples = 0;
};

/// Writes every measurement of `source` into the bag `path` (created or overwritten): images as mono8
/// sensor_msgs/Image (8-bit grey, as the stream gives them), IMU samples as sensor_msgs/Imu (no orientation:
/// orientation_covariance[0] = -1; the rate and angular-velocity / acceleration covariances from the rig's IMU
/// noise densities, σ² = density² · rate, when known). Header stamps and receive times are the measurement times
/// (they must be > 0). Reading the bag back with open_rosbag gives the same samples and the same pixels at the same
/// times. Throws IoError (file), ConfigError (options, e.g. a camera index the rig does not have), DataError (a
/// time ≤ 0, an image that is not 8-bit grey) and whatever the source throws.
RosbagWriteStats write_rosbag(Source& source, const Rig& rig, const std::string& path,
                              const RosbagWriteOptions& options = {});

}  // namespace rtslam::io
