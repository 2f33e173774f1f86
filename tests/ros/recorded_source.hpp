#pragma once
// A measurement stream read once and replayed as often as needed: rendering is the slow part of the simulator
// (much slower still under the sanitizers), and the ROS tests feed the same sequence to a writer, a node and a
// reference run.
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "rtslam/io/source.hpp"

namespace rtslam::ros_test {

class Recorded {
 public:
  explicit Recorded(io::Source& source) {
    while (auto m = source.next()) measurements_->push_back(std::move(*m));
  }
  const std::vector<io::Measurement>& measurements() const { return *measurements_; }
  /// A new stream over the recorded measurements (images share their pixels with the recording).
  std::unique_ptr<io::Source> replay() const { return std::make_unique<Replay>(measurements_); }

 private:
  using Measurements = std::vector<io::Measurement>;
  class Replay final : public io::Source {
   public:
    explicit Replay(std::shared_ptr<const Measurements> m) : m_(std::move(m)) {
      for (const auto& x : *m_) images_ += std::holds_alternative<io::ImageFrame>(x) ? 1 : 0;
    }
    std::optional<io::Measurement> next() override {
      if (i_ >= m_->size()) return std::nullopt;
      return (*m_)[i_++];
    }
    const io::SourceStats& stats() const override { return stats_; }
    std::optional<std::size_t> image_count() const override { return images_; }

   private:
    std::shared_ptr<const Measurements> m_;
    std::size_t i_ = 0;
    std::size_t images_ = 0;
    io::SourceStats stats_;
  };
  std::shared_ptr<Measurements> measurements_ = std::make_shared<Measurements>();
};

}  // namespace rtslam::ros_test
