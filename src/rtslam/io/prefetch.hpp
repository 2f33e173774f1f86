#pragma once
// Decoding ahead of the consumer, for Source::prefetch. Two ways:
//  - DecodeAhead: image files listed in stream order decoded by N worker threads (IndexedSource: every reader but
//    video and ROS bags). Only the pure decoding (read_grey_image) runs in the workers; the consumer takes the images
//    in order and keeps every check and the bad-input policy, so the stream is exactly the one without prefetch.
//  - PrefetchSource: any Source read one measurement ahead after another by one thread, into a bounded queue (video,
//    bags, the simulator's renderer): its errors reach the consumer after the measurements that preceded them.
// Both shut down in their destructor (workers told to stop, then joined): a consumer may stop reading at any time.
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <opencv2/core.hpp>

#include "rtslam/io/source.hpp"

namespace rtslam::io {

/// Decodes `paths` (in the order they will be taken) in `threads` worker threads, at most `depth` ahead of the
/// consumer's position.
class DecodeAhead {
 public:
  DecodeAhead(std::vector<std::string> paths, int threads, std::size_t depth);
  ~DecodeAhead();
  DecodeAhead(const DecodeAhead&) = delete;
  DecodeAhead& operator=(const DecodeAhead&) = delete;

  /// Image k of the list as read_grey_image(paths[k], why) gives it — except that a 16-bit image is left at its depth
  /// (keep_16bit), for the caller to scale in stream order —, waiting for its worker if needed. Positions
  /// must not decrease between calls; the ones skipped (a seek) are dropped. Rethrows what a worker's decoding threw.
  cv::Mat take(std::size_t k, std::string* why);
  /// Seconds take() waited so far.
  double wait_s() const { return wait_s_; }

 private:
  struct Result {
    cv::Mat image;
    std::string why;
    std::exception_ptr error;
  };
  void work();

  std::vector<std::string> paths_;
  std::size_t depth_;
  std::mutex mutex_;
  std::condition_variable work_cv_;  // workers: room to decode ahead, or stop
  std::condition_variable done_cv_;  // consumer: a result arrived
  std::size_t consumer_ = 0;         // the position the consumer takes next
  std::size_t next_ = 0;             // the next position handed to a worker
  std::map<std::size_t, Result> done_;
  bool stop_ = false;
  double wait_s_ = 0.0;
  std::vector<std::thread> workers_;
};

/// Reads `inner` ahead in one thread into a queue of at most `depth` measurements (0: 8). stats() are the inner
/// source's as they stood when the last measurement taken was read. A reader error is delivered by next() after
/// the measurements read before it, as without prefetch.
class PrefetchSource final : public Source {
 public:
  PrefetchSource(std::unique_ptr<Source> inner, std::size_t depth = 0);
  ~PrefetchSource() override;
  std::optional<Measurement> next() override;
  const SourceStats& stats() const override;
  std::optional<std::size_t> image_count() const override { return image_count_; }
  /// Forwarded to the inner source (its reader thread may be waiting in it); the destructor does it too.
  void interrupt() override { inner_->interrupt(); }

 private:
  struct Entry {
    std::optional<Measurement> m;  // nullopt with no error: the end
    std::exception_ptr error;
    std::shared_ptr<const SourceStats> stats;  // the inner stats after this read
  };
  void read();

  std::unique_ptr<Source> inner_;
  std::optional<std::size_t> image_count_;
  std::size_t depth_;
  std::mutex mutex_;
  std::condition_variable room_cv_, item_cv_;
  std::deque<Entry> queue_;
  bool stop_ = false;
  bool ended_ = false;  // consumer side: the end or an error was delivered
  std::shared_ptr<const SourceStats> stats_;
  std::thread reader_;
};

/// Turns prefetching on for `source` with `threads` decoding threads (0: off, < 0: default_prefetch_threads()):
/// through Source::prefetch where the source supports it, else by wrapping it in a PrefetchSource. Returns the
/// number of threads now decoding ahead (0: none).
int start_prefetch(std::unique_ptr<Source>& source, int threads);

}  // namespace rtslam::io
