#pragma once
// The image data manager for point landmarks (paper, sections 3 and 4.1; ../shared/MATH.md "One-point RANSAC").
// Per image of its camera:
//  1. predict every landmark's observation (h, compressed H, S = H P Hᵀ + R) and keep the visible ones whose 3σ
//     search box is not larger than `max_search_size_px2`; warp each landmark's initial patch into its predicted
//     appearance (plane homography, local affine model of the lens distortion). When fewer than `min_candidates`
//     boxes are that small (the filter became uncertain, e.g. across a dropped image), the visible landmarks with
//     the smallest boxes (clipped to the image) are kept too, up to `min_candidates` in all: without corrections
//     the uncertainty only grows, and no box would ever be small enough again;
//  2. one-point RANSAC doing the data association: up to `ransac_ntries` hypotheses, each from one candidate drawn
//     at random (seeded) among the untried ones and matched by ZNCC in its full n_sigma ellipse; the one-point
//     mean x_i = x ⊕ K_i (z_i − h_i) re-predicts every other candidate, which is searched only in the small box of
//     half-size `ransac_low_innov_px` around that prediction; the largest support set (ties: the earlier) is
//     corrected in one batched update when it holds at least 2 observations (at most `max_updates_ransac`);
//     hypotheses stop early (Civera et al. 2010's adaptive count) once, with the best support's share ε of the
//     candidates as the inlier ratio, the hypotheses so far (draws whose full search failed do not count) hold an
//     inlier with probability `ransac_confidence`: 1 − (1 − ε)^k ≥ confidence (ransac_may_stop);
//  3. the remaining candidates, by expected information (largest det S first; those of the min_candidates fallback
//     last), are re-predicted at the corrected state, searched in their (now small) n_sigma ellipses, gated by
//     Mahalanobis distance (n_sigma²) and corrected in `gain_recomputations` batched rounds, until `max_updates`
//     updates in the frame;
// With `time_budget_ms` > 0 the search of stages 2 and 3 stops anytime (the paper's real-time search): from the end
// of the predictions, the budget clock is read before each ZNCC search and, once the budget is spent, no new search
// starts — no further RANSAC hypothesis or support search, and the remaining candidates of stage 3 are skipped (not
// counted as failures for the map manager). What was matched is kept: the best support set and the candidates
// already matched are still gated and corrected. Since candidates are searched by decreasing det S, the ones left
// out are those whose observation was expected to bring the least information. FrameStats counts the skipped
// landmarks, whether the budget cut the frame and the time used. Off (0), the clock is never read and the result
// does not depend on time.
//  4. initialization: in the empty cells of the randomly moving grid, the best Harris corner of the cell becomes an
//     undelayed AHP landmark (at most `max_inits` per frame, if the map manager has room); its descriptor is the
//     `init_patch_size` patch around the corner plus the sensor pose T_WS it was seen from.
// Unmatched and gated-out observations count as failures for the map manager. The same seed and images give the
// same result. Buffers are reserved once: a frame allocates nothing after warm-up.
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rtslam/core/random.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/models/landmarks/ahp.hpp"
#include "rtslam/slam/batch_correction.hpp"
#include "rtslam/slam/managers.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/strategies/init_grid.hpp"
#include "rtslam/vision/harris.hpp"
#include "rtslam/vision/image.hpp"
#include "rtslam/vision/zncc.hpp"

namespace rtslam::strategies {

/// One grey image of one camera (non-owning: the pixels must live while process() runs).
struct RawImage : slam::RawData {
  vision::ImageView image;
};

/// The appearance descriptor of a point landmark: its initial patch (odd square), the image pixel of the patch's
/// centre, the landmark's (distorted, sub-pixel) pixel in that image, and the sensor pose the patch was taken from.
struct PointDescriptor {
  vision::Image patch;
  Eigen::Vector2d patch_centre_px = Eigen::Vector2d::Zero();
  Eigen::Vector2d z0_px = Eigen::Vector2d::Zero();
  Eigen::Matrix2d J_dist_undist_0 = Eigen::Matrix2d::Identity();  // pixel-level, at z0 (identity: no distortion)
  math::Pose T_WS0;
};
using PointDescriptorPtr = std::shared_ptr<const PointDescriptor>;

/// The descriptor of a landmark made by this data manager (or by a known-landmark initialization), or nullptr.
const PointDescriptor* point_descriptor(const slam::Landmark& lmk);

/// One-point RANSAC's adaptive stop (Civera et al. 2010, after Fischler and Bolles): true when `hypotheses` drawn
/// among `candidates`, of which at least `best_support` are inliers (the largest support found), hold at least one
/// inlier with probability `confidence`: 1 − (1 − ε)^hypotheses ≥ confidence with ε = best_support / candidates.
/// False when confidence is 0 (off), no candidate or hypothesis is counted, or best_support < 2 (no support set to
/// correct with yet).
bool ransac_may_stop(int hypotheses, int best_support, int candidates, double confidence);

struct ActiveSearchOptions {
  double sigma_px = 1.0;              // measurement noise (px), RT-SLAM PIX_NOISE
  bool second_order_depth = true;     // add the inverse-depth linearization term to R (slam/observation.hpp)
  double n_sigma = 3.0;               // search ellipse and gate (RT-SLAM MAHALANOBIS_TH)
  int max_updates = 25;               // RT-SLAM N_UPDATES_TOTAL
  int max_updates_ransac = 22;        // RT-SLAM N_UPDATES_RANSAC (at most 32: one batched correction)
  int ransac_ntries = 6;              // RT-SLAM RANSAC_NTRIES (0 disables RANSAC: plain gated active search)
  double ransac_confidence = 0.99;    // stop hypothesizing once an inlier was drawn with this probability (0: never)
  double ransac_low_innov_px = 1.0;   // RT-SLAM RANSAC_LOW_INNOV: half-size of the hypothesis support box (px)
  int gain_recomputations = 3;        // RT-SLAM N_RECOMP_GAINS
  int iterations = 1;                 // corrections relinearized this many times at most (1: EKF; > 1: iterated EKF)
  double iteration_tolerance = 1e-6;  // ... until the correction changes by less than this (m, rad) between two
  int max_inits = 10;                 // RT-SLAM N_INIT
  double max_search_size_px2 = 10000; // RT-SLAM MAX_SEARCH_SIZE: skip larger search boxes (px²)
  // Fewer boxes within max_search_size_px2 than this: the smallest larger ones are searched too, up to this many
  // candidates (0: never, as RT-SLAM). 4: one more than the health monitor's min_updated, so that one failed match
  // still leaves a frame that counts as tracked.
  int min_candidates = 4;
  double margin_px = 8.0;             // predictions closer to the border are not visible
  int init_patch_size = 31;           // descriptor patch (odd); the matched patch size is zncc.patch_size
  InitGridOptions grid;               // RT-SLAM GRID_HCELLS 6, GRID_VCELLS 4
  models::AhpPrior prior;             // RT-SLAM D_MIN 0.5 m
  // fixed: every new landmark gets the prior of d_min (RT-SLAM). scene: once the frame has updated at least
  // `scene_prior_min_points` Euclidean (converged) landmarks, new landmarks get ρ̄ = 1/d_med, σ_ρ = 1/(2 d_med)
  // with d_med their median distance from the camera (2σ spans [d_med/2, ∞)); d_min is the prior until then. Each
  // new landmark's prior carries information on the map's scale: a fixed mean far from the scene's depths pulls
  // the scale towards it (a 1–13 % scale error on the recorded V1_01 flight), a mean taken from the map does not.
  std::string depth_prior = "scene";
  int scene_prior_min_points = 3;
  // Stop-anytime search: wall time (ms) for stages 2 and 3 (RANSAC, active search and their corrections) from the
  // end of the predictions; 0: off. `rtslam run --realtime` sets one from the frame period when this is 0
  // (docs/configuration.md).
  double time_budget_ms = 0.0;
  vision::HarrisOptions harris;
  vision::ZnccOptions zncc;           // MATCH_TH 0.90, patch 15
  static constexpr double kMaxTimeBudgetMs = 10000.0;
  /// `where` names the options in messages (their config section, e.g. "search/zncc", or the file and section).
  void validate(const std::string& where = "search") const;
  /// Keys: sigma_px, second_order_depth, n_sigma, max_updates, max_updates_ransac, ransac_ntries, ransac_confidence,
  /// ransac_low_innov_px,
  /// gain_recomputations, max_inits, max_search_size_px2, min_candidates, margin_px, init_patch_size, d_min,
  /// time_budget_ms, grid: {cells_x, cells_y, margin_px}, harris: {...}, zncc: {...}. Unknown keys are errors;
  /// validates.
  static ActiveSearchOptions from_yaml(YamlMap& map);
  /// The keys of from_yaml with their values (the effective configuration).
  YAML::Node to_yaml() const;
};

/// The clock of the search's time budget: milliseconds on a monotonic scale (any origin). The default reads
/// std::chrono::steady_clock; tests inject a fake one (e.g. one that advances at each reading, that is at each
/// search attempt).
class BudgetClock {
 public:
  virtual ~BudgetClock() = default;
  virtual double now_ms() = 0;
};

class ActiveSearchDataManager final : public slam::DataManager {
 public:
  static constexpr int kMaxBatch = 32;  // observations in one batched correction
  // Remembered ZNCC scores per landmark and frame (vision::ScoreMemo): the RANSAC boxes and the climbs of one
  // landmark ask for a few dozen positions.
  static constexpr int kMemoEntries = 128;
  ActiveSearchDataManager(ActiveSearchOptions options, const slam::MapManager& map_manager, int width, int height,
                          std::uint64_t seed);
  void process(slam::Map& map, slam::Sensor& sensor, const slam::RawData& raw, long frame,
               slam::FrameStats& stats) override;
  std::string name() const override { return "active-search"; }
  /// The views of the patches of the landmarks `sensor` made (PointDescriptor::T_WS0) move with the map.
  void scale_lengths(slam::Map& map, const slam::Sensor& sensor, double c, const Eigen::Vector3d& centre) override;
  const ActiveSearchOptions& options() const { return opt_; }
  /// A scene depth known from elsewhere (the visual-inertial start's features, m): with depth_prior scene, new
  /// landmarks take the prior of this depth until the map's own converged landmarks give one (0: none).
  void set_depth_hint(double depth_m) { depth_hint_m_ = depth_m > 0.0 && std::isfinite(depth_m) ? depth_m : 0.0; }
  /// First-estimate Jacobians for the observations (slam/consistency: fej; see process()).
  void set_first_estimate_jacobians(bool on) { fej_ = on; }
  /// The clock the time budget is measured with (not owned; must outlive the manager); nullptr: steady_clock.
  void set_budget_clock(BudgetClock* clock);
  /// ZNCC searches (full ellipses and RANSAC support boxes) run in the last frame.
  int last_frame_searches() const { return searches_; }

  /// What happened to one visible observation in the last frame (overlays, tests).
  struct FrameMatch {
    int landmark_id = -1;
    Eigen::Vector2d h = Eigen::Vector2d::Zero();  // first prediction of the frame
    Eigen::Matrix2d S = Eigen::Matrix2d::Identity();
    Eigen::Vector2d z = Eigen::Vector2d::Zero();  // measurement (when matched)
    double score = 0.0;
    bool searched = false;
    bool matched = false;
    bool ransac_inlier = false;  // in the best support set
    bool updated = false;        // used in a correction
  };
  const std::vector<FrameMatch>& last_frame() const { return report_; }
  /// The randomly moving initialization grid as the last frame left it (overlays: viz::make_report).
  const InitGrid& grid() const { return grid_; }

 private:
  struct Candidate {
    slam::Observation* obs = nullptr;
    int slot = 0;                  // index of its predicted patch
    Eigen::Vector2d h0 = Eigen::Vector2d::Zero();
    Eigen::Matrix2d S0 = Eigen::Matrix2d::Identity();
    double det0 = 1.0;             // det S0 (the search order)
    bool fallback = false;         // admitted by the min_candidates fallback (its box above max_search_size_px2)
    bool tried = false;            // drawn as a RANSAC hypothesis
    bool full_searched = false;    // searched in its full ellipse (result below)
    bool full_matched = false;
    bool searched = false;
    bool matched = false;
    bool done = false;             // updated, or failed for good in this frame
    Eigen::Vector2d z = Eigen::Vector2d::Zero();
    double score = 0.0;
    bool inlier = false;
    bool updated = false;
  };

  bool predict_patch(const slam::Map& map, const slam::Sensor& sensor, const slam::Observation& obs, int slot);
  /// Searches a candidate's predicted patch in `region`; fills z/score on success.
  bool search(Candidate& c, const vision::SearchEllipse& region, vision::ZnccMatcher& matcher,
              Eigen::Vector2d& z, double& score);
  /// One batched correction of the given candidates (measurements z, re-predicted at the current mean).
  bool correct_batch(slam::Map& map, const std::vector<Candidate*>& batch);
  void initialize(slam::Map& map, slam::Sensor& sensor, long frame, slam::FrameStats& stats);
  /// The prior for this frame's new landmarks (depth_prior: fixed or scene, see the options).
  models::AhpPrior frame_prior(const slam::Map& map, const slam::Sensor& sensor);

  ActiveSearchOptions opt_;
  const slam::MapManager& map_manager_;
  InitGrid grid_;
  Rng rng_;
  double match_ms_ = 0.0;              // time spent in search() this frame
  int searches_ = 0;                   // search() calls this frame
  BudgetClock* clock_ = nullptr;       // the budget's clock (default_clock_ unless set)
  // The frame's budget (time_budget_ms > 0): start reading and whether it is spent.
  double budget_start_ms_ = 0.0;
  bool budget_spent_ = false;
  /// Whether a new search may start (always with the budget off; reads the clock otherwise).
  bool may_search();
  vision::ZnccMatcher matcher_;        // full ellipses (two-level as configured)
  vision::ZnccMatcher matcher_small_;  // tiny RANSAC boxes: exhaustive
  int reserved_width_ = 0, reserved_height_ = 0;  // image size the matchers' buffers were grown for
  vision::HarrisDetector harris_;
  vision::ImageView image_;
  std::vector<double> depths_;  // scene prior: distances of this frame's updated Euclidean landmarks
  bool fej_ = false;
  double depth_hint_m_ = 0.0;
  Eigen::VectorXd fej_mean_;  // the linearization mean of the frame (first-estimate Jacobians)
  const Eigen::VectorXd* lin() const { return fej_ ? &fej_mean_ : nullptr; }
  std::vector<Candidate> candidates_;
  std::vector<Candidate*> order_;
  // Visible landmarks whose search box exceeded max_search_size_px2 in step 1, with its area clipped to the image.
  struct Oversized {
    double area = 0.0;
    int order = 0;  // in the map
    slam::Observation* obs = nullptr;
  };
  std::vector<Oversized> oversized_;
  std::vector<vision::Image> warp_buf_;
  std::vector<vision::Patch> patches_;
  std::vector<vision::ScoreMemo> memos_;  // per slot: its patch's scores in this frame's image (every search reuses)
  std::vector<int> untried_;
  std::vector<int> support_;
  std::vector<int> best_support_;
  std::vector<Eigen::Vector2d> support_z_;
  std::vector<Eigen::Vector2d> best_support_z_;
  std::vector<Candidate*> batch_;
  std::vector<slam::Observation*> batch_obs_;
  slam::BatchCorrector corrector_{kMaxBatch};
  Eigen::VectorXd dx_;
  Eigen::VectorXd hyp_mean_;
  std::vector<FrameMatch> report_;
};

}  // namespace rtslam::strategies
