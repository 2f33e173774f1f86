#pragma once
// A data manager for point measurements whose association is known (simulated "perfect front end"): the walking
// skeleton's, and a reference for testing the estimator apart from image processing. Per frame:
//  1. predict every landmark's observation (h, H, S) and keep the visible ones;
//  2. active search ordered by expected information (largest innovation covariance first), at most
//     `max_updates` per frame, in `gain_recomputations` rounds (RT-SLAM N_RECOMP_GAINS): each round takes the
//     next candidates, looks their points up among the measurements, re-predicts them at the current estimate,
//     gates each at `n_sigma` (Mahalanobis) and corrects the survivors in one batched update;
//  3. initialize up to `max_inits` new AHP landmarks in empty cells of the randomly moving grid, picking in each
//     cell the unmapped measured point nearest the cell centre.
#include <cstdint>
#include <vector>

#include "rtslam/core/random.hpp"
#include "rtslam/models/landmarks/ahp.hpp"
#include "rtslam/slam/batch_correction.hpp"
#include "rtslam/slam/managers.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/strategies/init_grid.hpp"

namespace rtslam::strategies {

/// One measured image point with its true identity.
struct PointMeasurement {
  int point_id = 0;
  Eigen::Vector2d z = Eigen::Vector2d::Zero();
};

struct RawPoints final : slam::RawData {
  std::vector<PointMeasurement> points;
};

struct KnownAssociationOptions {
  double sigma_px = 1.0;          // measurement noise (px)
  double n_sigma = 3.0;           // gate: Mahalanobis distance (RT-SLAM MAHALANOBIS_TH)
  int max_updates = 25;           // RT-SLAM N_UPDATES_TOTAL
  int max_inits = 10;             // RT-SLAM N_INIT
  int gain_recomputations = 3;    // RT-SLAM N_RECOMP_GAINS: batched corrections per frame
  double margin_px = 8.0;         // predictions closer to the border are not visible
  InitGridOptions grid;
  models::AhpPrior prior;
  void validate() const;
};

class KnownAssociationDataManager final : public slam::DataManager {
 public:
  KnownAssociationDataManager(KnownAssociationOptions options, const slam::MapManager& map_manager, int width,
                              int height, std::uint64_t seed);
  void process(slam::Map& map, slam::Sensor& sensor, const slam::RawData& raw, long frame,
               slam::FrameStats& stats) override;
  std::string name() const override { return "known-association"; }

 private:
  KnownAssociationOptions opt_;
  const slam::MapManager& map_manager_;
  InitGrid grid_;
  Rng rng_;
  std::vector<int> measurement_of_point_;  // point id → index in the frame's measurements, −1 if absent
  std::vector<char> point_in_map_;
  std::vector<slam::Observation*> candidates_;
  std::vector<slam::Observation*> batch_;
  slam::BatchCorrector corrector_;
};

}  // namespace rtslam::strategies
