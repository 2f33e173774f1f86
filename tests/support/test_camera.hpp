#pragma once
// The tests' cameras (tests that need other values set them on a copy):
//  - vga_camera: 640×480, f = 400 px, principal point at the centre, no distortion;
//  - euroc_camera: 752×480, f = 458 px, principal point off the centre as EuRoC's cam0, no distortion;
//    euroc_camera_radtan: the same with radial-tangential distortion of EuRoC's size;
//  - qvga_camera: 320×240, f = 250 px, principal point at the centre (the small rigs of the strategies' tests).
#include "rtslam/models/sensors/pinhole_camera.hpp"

namespace rtslam::support {

inline models::CameraIntrinsics vga_camera() {
  models::CameraIntrinsics c;
  c.width = 640;
  c.height = 480;
  c.fx = c.fy = 400.0;
  c.cx = 320.0;
  c.cy = 240.0;
  return c;
}

inline models::CameraIntrinsics euroc_camera() {
  models::CameraIntrinsics c;
  c.width = 752;
  c.height = 480;
  c.fx = c.fy = 458.0;
  c.cx = 367.0;
  c.cy = 248.0;
  return c;
}

inline models::CameraIntrinsics euroc_camera_radtan() {
  models::CameraIntrinsics c = euroc_camera();
  c.model = models::DistortionModel::RadTan;
  c.coeffs = {-0.28, 0.07, 2e-4, 2e-5};
  return c;
}

inline models::CameraIntrinsics qvga_camera() {
  models::CameraIntrinsics c;
  c.width = 320;
  c.height = 240;
  c.fx = c.fy = 250.0;
  c.cx = 159.5;
  c.cy = 119.5;
  return c;
}

}  // namespace rtslam::support
