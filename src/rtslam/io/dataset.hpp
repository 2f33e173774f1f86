#pragma once
// Opening a dataset: "KIND:PATH" or "PATH" (kind auto-detected) -> a measurement Source, the Rig calibration,
// optional ground truth, and a name. Layouts (details in docs/datasets.md):
//   euroc   EuRoC / ASL folder (PATH or PATH/mav0 with cam*/data.csv, imu0/data.csv, sensor.yaml files,
//           optional state_groundtruth_estimate0/data.csv); also TUM-VI's export (no sensor.yaml: dso/camchain.yaml
//           and dso/imu_config.yaml beside mav0/, mocap0/data.csv as ground truth).
//   tum     TUM RGB-D / mono: rgb.txt (`t path`), optional groundtruth.txt; calibration YAML from the option or
//           calibration.yaml / camera.yaml / sensor.yaml / camchain.yaml in the folder.
//   kitti   KITTI odometry sequences/NN: image_0/*.png, times.txt, calib.txt (P0), optional ../../poses/NN.txt.
//   images  a folder of images (or its frames/ subfolder), sorted by name with numbers compared as numbers;
//           timestamps from a file (option, or times.txt / timestamps.txt) or a fixed rate; calibration from the
//           option or camera.json / calibration.yaml / camera.yaml / sensor.yaml / camchain.yaml in the folder.
//           The MonoSLAM Davison sequence is one: frames/*.pgm + camera.json (give rate 30 Hz, see calibration.hpp).
//   video   a video file read with OpenCV; calibration from the option or next to the file.
//   rosbag  a ROS1 bag (sensor_msgs/Image or CompressedImage and sensor_msgs/Imu topics, EuRoC's names by
//           default); calibration from the option (a file or an EuRoC folder) or next to the bag. Only in builds
//           with ROS (rosbag_source.hpp); detected by the .bag extension.
//   camera  live input, never detected: camera:N (/dev/videoN through OpenCV's V4L2 backend) or camera:FILE (a video
//           played in a loop at its rate, standing in for a device); needs the calibration option; endless
//           (camera_source.hpp).
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "rtslam/core/trajectory.hpp"
#include "rtslam/io/calibration.hpp"
#include "rtslam/io/imu_stream.hpp"
#include "rtslam/io/source.hpp"

namespace rtslam::io {

struct DatasetOptions {
  BadInputPolicy bad_input = BadInputPolicy::Error;
  std::vector<int> cameras = {0};  // cameras to stream (EuRoC camN folders / KITTI image_N); the Rig has these only
  bool use_imu = true;             // stream IMU samples when the dataset has them
  double rate_hz = 0.0;            // image rate for image folders and videos (0 = from timestamps/calibration/video)
  std::string calibration;         // calibration file overriding the dataset's own
  std::string timestamps;          // timestamps file for image folders
  int max_imu_dropout = 3;         // more missing IMU samples than this in a row is a gap (reported)
  double start_offset_s = 0.0;     // start this many seconds after the stream's first measurement (WindowSource)
  double duration_s = 0.0;         // stop after this many seconds (0: to the end)
  // rosbag: the image topic of each streamed camera, in the order of `cameras` (empty: /camN/image_raw for each
  // N, EuRoC's names); the IMU topic (empty: no IMU); stamps from the bag's receive times instead of the messages'
  // header stamps.
  std::vector<std::string> image_topics;
  std::string imu_topic = "/imu0";
  bool bag_receive_time = false;
  // camera: inputs: a live IMU stream paired with the camera (imu_stream.hpp: a FIFO, a serial device, a file or "-";
  // empty: none; read only when use_imu is set) and the clock of its times.
  std::string imu_stream;
  ImuStreamClock imu_clock = ImuStreamClock::Host;

  static constexpr double kMinRateHz = 1e-3, kMaxRateHz = 1e5;  // rate_hz, when given
  static constexpr int kMaxImuDropout = 1'000'000;
  static constexpr int kMaxCameraIndex = 15;
  /// Throws ConfigError naming the option (and its CLI flag) and the bound: rate_hz 0 or in [1e-3, 1e5] Hz,
  /// max_imu_dropout in [0, 1e6], start_offset_s and duration_s in [0, 9.2e9] s, cameras in [0, 15].
  void validate() const;
};

struct Dataset {
  std::string name;  // e.g. "euroc-v101-static"
  std::string kind;  // "euroc", "tum", "kitti", "images", "video", "rosbag", "camera"
  std::string path;  // the dataset root as opened
  std::unique_ptr<Source> source;
  Rig rig;
  std::optional<Trajectory> ground_truth;  // T_WR of the robot frame (IMU on EuRoC, camera 0 on KITTI/TUM)
};

/// Detects the kind of a path ("euroc", "tum", "kitti", "images", "video", "rosbag"); throws IoError when it cannot.
std::string detect_dataset_kind(const std::string& path);

/// The ground truth of an EuRoC-format folder `mav0`: EuRoC's state_groundtruth_estimate0/data.csv, else TUM-VI's
/// mocap0/data.csv (`t[ns], p, q(w x y z)` of the IMU); empty when it has neither.
std::string euroc_ground_truth_file(const std::string& mav0);

/// Opens "KIND:PATH" or "PATH". Throws IoError/ConfigError/DataError naming the file and the problem.
Dataset open_dataset(const std::string& spec, const DatasetOptions& options = {});

/// Image files of a folder (png, pgm, ppm, jpg, jpeg, bmp, tif, tiff), sorted by name with digit runs compared
/// numerically ("img2" before "img10").
std::vector<std::string> list_images(const std::string& folder);

}  // namespace rtslam::io
