#pragma once
// The tests' plain camera: 640×480, f = 400 px, principal point at the centre, no distortion (tests that need
// distortion or other values set them on a copy).
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

}  // namespace rtslam::support
