#pragma once
// viz::Viewer: the live web viewer of a run (`rtslam run --view [ADDR:PORT]`) and the replay of a finished one
// (`rtslam view OUT`). An HTTP + WebSocket server (CivetWeb) on ADDR:PORT — loopback by default, port 0 picks a
// free one — serves the page (embedded into the binary, three.js included: works offline) and pushes to every
// connected browser the current image with its overlay (draw_overlay, JPEG), the map (landmarks with their 3σ
// uncertainty, AHP and Euclidean told apart), the trajectory, the ground truth aligned to the estimate, and the
// per-frame plots (matches, pose NEES, NIS, time). A browser connecting late gets the whole trajectory and plots.
//
// Wiring into a run (all the API there is):
//
//   viz::Viewer viewer(viz::ViewerOptions{.address = "127.0.0.1:0"});  // starts the server, or throws IoError
//   std::cout << "viewer: " << viewer.url() << "\n";
//   viewer.set_title(dataset.name);                                       // optional
//   if (dataset.ground_truth) viewer.set_ground_truth(*dataset.ground_truth);  // optional: NEES, GT path
//   ... observer of run_image_slam, on the filter thread:
//       viewer.push(viz::make_report(frame, image, &stats));              // never blocks (see push)
//   viewer.finish();                                                      // the page says "finished"
//   ... keep the process alive while the user looks (e.g. until Ctrl-C), then ~Viewer() stops it.
//
// The viewer never slows the filter: push() copies a small per-frame record (pose, covariance, counts, NIS) into
// the history and moves the report into a bounded queue (ViewerOptions::queue_frames) that drops its OLDEST report
// when full; both are wait-free (atomic exchanges, no mutex shared with the viewer thread: latest_queue.hpp), and
// the dropped report is freed on the caller's thread. Everything else — NEES,
// alignment, the overlay drawing, JPEG encoding, JSON, the network — runs on the viewer's own thread (at a lower
// scheduling priority), and only while a browser is connected. A browser gets at most max_fps frames per second
// and only when it has shown the previous one (slow browsers skip frames, never the filter).
#include <memory>
#include <string>

#include "rtslam/core/trajectory.hpp"
#include "rtslam/viz/overlay.hpp"
#include "rtslam/viz/replay.hpp"
#include "rtslam/viz/report.hpp"

namespace rtslam::viz {

struct ViewerOptions {
  std::string address = "127.0.0.1:0";  // IPv4:PORT or PORT (then 127.0.0.1); 0.0.0.0 listens on all interfaces
  int queue_frames = 4;                 // reports waiting for the viewer thread (older ones are dropped), >= 1
  double max_fps = 25.0;                // frames sent to one browser per second at most, > 0
  int jpeg_quality = 85;                // of the overlay image sent, in [10, 100]
  int max_image_width = 1280;           // wider overlays are downscaled before encoding (0: never)
  std::string ground_truth_alignment = "sim3";  // how the GT is drawn in the estimate's frame: sim3|se3|posyaw|origin
  bool lower_priority = true;           // the viewer thread runs at nice +10 (Linux)
  int max_history = 20000;              // per-frame records kept (a live run: the older half is thinned to every
                                        // other record whenever there are more, so memory stays bounded), >= 100
  int write_timeout_ms = 10000;         // a page that takes no byte of a message for this long is cut off (it
                                        // reconnects at its next ping); also an HTTP request's time, [100, 600000]
  OverlayOptions overlay;
  void validate() const;                // throws ConfigError naming the option, the value and the bound
};

/// Counters, for tests and the status line.
struct ViewerStats {
  long pushed = 0;     // reports pushed
  long dropped = 0;    // reports dropped by the queue (never processed by the viewer thread)
  long processed = 0;  // reports taken by the viewer thread
  long frames_sent = 0;  // frame messages sent (all browsers)
  int clients = 0;     // connected browsers
  long history_dropped = 0;  // per-frame records lost because the viewer thread was starved for 4096 frames
  long pages_cut = 0;  // pages whose stream a failed write cut (write_timeout_ms or a broken connection), each
                       // closed at its next message
};

class Viewer {
 public:
  /// Starts the server and the viewer thread. Throws ConfigError for bad options (e.g. an address that is not
  /// IPv4:PORT) and IoError when the address cannot be bound.
  explicit Viewer(ViewerOptions options = {});
  /// Stops (stop()).
  ~Viewer();
  Viewer(const Viewer&) = delete;
  Viewer& operator=(const Viewer&) = delete;

  /// "http://127.0.0.1:PORT/" (for 0.0.0.0: the loopback URL).
  std::string url() const;
  int port() const;

  /// A title for the page (dataset name, ...). Thread-safe.
  void set_title(const std::string& title);
  /// The ground truth of the run (T_WR), any time before or during the run: the page draws it aligned to the
  /// estimate (ViewerOptions::ground_truth_alignment, refitted as the trajectory grows) and plots the pose NEES
  /// (eval/nees.hpp). Thread-safe.
  void set_ground_truth(const Trajectory& ground_truth);

  /// Hands one processed frame to the viewer, from ONE thread (the filter's). Never blocks: see the header comment.
  /// Returns false when the queue
  /// was full and its oldest report was dropped (the history keeps every frame's record regardless).
  bool push(FrameReport report);
  /// The run has ended: the page says so. The server keeps serving until stop().
  void finish();

  /// Serves a finished run (rtslam view) instead of a live one; call once, before any push.
  void show_recording(RunRecording recording);

  ViewerStats stats() const;
  /// Closes the browsers' connections, stops the viewer thread and the server. Idempotent; called by ~Viewer.
  void stop();

  class Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

/// "ADDR:PORT" or "PORT" → (IPv4 address, port); throws ConfigError naming the value otherwise.
std::pair<std::string, int> parse_address(const std::string& address);

}  // namespace rtslam::viz
