// rtslam: the command-line entry point. Thin: parses, wires, reports; the work lives in the libraries.
#include <cstdlib>
#include <exception>
#include <iostream>

#include "commands.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/io/codecs.hpp"

int main(int argc, char** argv) {
  // FFmpeg's own messages on a corrupt video ("moov atom not found", "overread 8") would come before our one-line
  // error: off unless the user set OpenCV's variable. Set here, before any thread reads the environment.
  ::setenv("OPENCV_FFMPEG_LOGLEVEL", "-8", 0);  // AV_LOG_QUIET
  CLI::App app{"rtslam: real-time EKF-SLAM for cameras and IMUs (RT-SLAM)"};
  app.require_subcommand(1);
  std::string log_level = "info";
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error or off")->capture_default_str();
  app.parse_complete_callback([&log_level] { rtslam::set_log_level(log_level); });
  // The version, and where OpenCV's codecs come from (loaded here, as a check; other commands load them only when
  // they read a video or an image format of OpenCV's, or write images).
  app.set_version_flag("--version", [] {
    std::string codecs;
    try {
      codecs = "OpenCV codecs plugin: " + rtslam::io::codecs::load_plugin();
    } catch (const rtslam::Error& e) {
      codecs = e.what();  // "OpenCV codecs plugin ... not loaded: tried ..."
    }
    return std::string("rtslam " RTSLAM_VERSION "\n") + codecs;
  });

  rtslam::cli::register_run(app);
  rtslam::cli::register_simulate(app);
  rtslam::cli::register_eval(app);
  rtslam::cli::register_batch(app);
  rtslam::cli::register_report(app);
  rtslam::cli::register_bench(app);
  rtslam::cli::register_imu_noise(app);
  rtslam::cli::register_view(app);
  rtslam::cli::register_check_calibration(app);
  rtslam::cli::register_soak(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const rtslam::cli::CommandExit& e) {
    return e.code;
  } catch (const rtslam::Error& e) {
    std::cerr << "rtslam: error: " << e.what() << '\n';
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "rtslam: unexpected error: " << e.what() << '\n';
    return 1;
  }
  return 0;
}
