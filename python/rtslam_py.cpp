// The `rtslam` Python module (docs/python.md): image SLAM on a dataset or the simulator, its trajectory, map and
// per-frame statistics as numpy arrays, and the ATE of the eval module.
//
// Arrays: a trajectory is N×8, rows [t (s), x y z (m), qw qx qy qz] of T_WR (robot R in world W), the layout of
// TUM files with the quaternion scalar first; landmarks M×3 Euclidean positions in W (m).
// Errors: rtslam::ConfigError → rtslam.ConfigError (a ValueError), IoError → rtslam.IoError (an OSError), DataError
// and InvariantError → rtslam.DataError / rtslam.InvariantError (RuntimeErrors), with the library's one-line message.
// The GIL is released while the filter runs; an `on_frame` callback takes it back for its own call, and so does a
// check for signals after each image (Ctrl-C raises KeyboardInterrupt during a run). A Session may be used from
// several threads: its calls take turns (one lock, taken with the GIL released).
#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <atomic>
#include <cmath>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/trajectory.hpp"
#include "rtslam/eval/metrics.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/pipeline/default_config.hpp"
#include "rtslam/pipeline/image_slam.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/slam/robot.hpp"
#include "rtslam/slam/system.hpp"

namespace py = pybind11;
using namespace rtslam;

namespace {

using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;

// Trajectory → N×8 [t_s x y z qw qx qy qz].
Array to_array(const Trajectory& traj) {
  Array a({static_cast<py::ssize_t>(traj.poses.size()), py::ssize_t{8}});
  auto m = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < traj.poses.size(); ++i) {
    const StampedPose& s = traj.poses[i];
    const auto r = static_cast<py::ssize_t>(i);
    m(r, 0) = to_seconds(s.t);
    for (int k = 0; k < 3; ++k) m(r, 1 + k) = s.p_WR[k];
    m(r, 4) = s.q_WR.w();
    m(r, 5) = s.q_WR.x();
    m(r, 6) = s.q_WR.y();
    m(r, 7) = s.q_WR.z();
  }
  return a;
}

// N×8 [t_s x y z qw qx qy qz] → Trajectory (quaternions normalized); ValueError naming `what` on a bad shape.
Trajectory to_trajectory(const Array& a, const char* what) {
  if (a.ndim() != 2 || a.shape(1) != 8) {
    throw ConfigError(std::string(what) + ": expected an N×8 array [t x y z qw qx qy qz]");
  }
  Trajectory traj;
  traj.source = what;
  auto m = a.unchecked<2>();
  for (py::ssize_t r = 0; r < a.shape(0); ++r) {
    for (py::ssize_t k = 0; k < 8; ++k) {
      if (!std::isfinite(m(r, k))) {
        throw ConfigError(std::string(what) + ": non-finite value at row " + std::to_string(r) + ", column " +
                          std::to_string(k));
      }
    }
    StampedPose s;
    const std::optional<TimeNs> t = from_seconds_checked(m(r, 0));
    if (!t) {
      throw ConfigError(std::string(what) + ": time " + std::to_string(m(r, 0)) + " s at row " + std::to_string(r) +
                        " is beyond the int64 nanosecond range");
    }
    s.t = *t;
    s.p_WR = Eigen::Vector3d(m(r, 1), m(r, 2), m(r, 3));
    s.q_WR = Eigen::Quaterniond(m(r, 4), m(r, 5), m(r, 6), m(r, 7));
    if (!(s.q_WR.norm() > 0.0)) throw ConfigError(std::string(what) + ": zero quaternion at row " + std::to_string(r));
    s.q_WR.normalize();
    traj.poses.push_back(s);
  }
  return traj;
}

// The result of a run, as Python objects (built with the GIL held, after the run).
struct PyResult {
  Array trajectory;
  py::array_t<std::int64_t> timestamps_ns;
  Array landmarks;
  py::list frames;
  py::object ground_truth = py::none();
  int resets = 0;
  int frames_lost = 0;
  int frames_diverged = 0;
  bool inertial = false;
  std::string inertial_start;
  int landmarks_created = 0;
};

py::dict frame_dict(const slam::FrameStats& f) {
  py::dict d;
  d["t"] = to_seconds(f.t);
  d["t_ns"] = f.t;
  d["landmarks_in_map"] = f.landmarks_in_map;
  d["visible"] = f.visible;
  d["searched"] = f.searched;
  d["matched"] = f.matched;
  d["updated"] = f.updated;
  d["initialized"] = f.initialized;
  d["ransac_inliers"] = f.ransac_inliers;
  d["reparametrized"] = f.reparametrized;
  d["removed"] = f.removed;
  d["refused"] = f.refused;
  d["nis"] = f.nis;
  d["nis_count"] = f.nis_count;
  d["health"] = f.health;
  d["reset"] = f.reset;
  d["budget_hit"] = f.budget_hit;
  d["budget_skipped"] = f.budget_skipped;
  d["time_search_ms"] = f.time_search_ms;
  d["search_fallback"] = f.fallback;
  d["zero_velocity"] = f.zero_velocity;
  d["time_ms"] = f.time_total_ms;
  return d;
}

PyResult to_py(const pipeline::ImageSlamResult& r, const std::optional<Trajectory>& ground_truth) {
  PyResult out;
  out.trajectory = to_array(r.estimate);
  out.timestamps_ns = py::array_t<std::int64_t>(static_cast<py::ssize_t>(r.estimate.poses.size()));
  auto ts = out.timestamps_ns.mutable_unchecked<1>();
  for (std::size_t i = 0; i < r.estimate.poses.size(); ++i) ts(static_cast<py::ssize_t>(i)) = r.estimate.poses[i].t;
  out.landmarks = Array({static_cast<py::ssize_t>(r.landmark_positions.size()), py::ssize_t{3}});
  auto lm = out.landmarks.mutable_unchecked<2>();
  for (std::size_t i = 0; i < r.landmark_positions.size(); ++i) {
    for (int k = 0; k < 3; ++k) lm(static_cast<py::ssize_t>(i), k) = r.landmark_positions[i][k];
  }
  for (const slam::FrameStats& f : r.frames) out.frames.append(frame_dict(f));
  if (ground_truth) out.ground_truth = to_array(*ground_truth);
  out.resets = r.resets;
  out.frames_lost = r.frames_lost;
  out.frames_diverged = r.frames_diverged;
  out.inertial = r.inertial;
  out.inertial_start = r.inertial_start;
  out.landmarks_created = r.landmarks_created;
  return out;
}

// The dataset of a run: 'KIND:PATH' as `rtslam run --dataset` opens it, or the simulator.
io::Dataset open_run_dataset(const pipeline::ImageSlamOptions& options, const std::optional<std::string>& dataset) {
  if (!dataset) return pipeline::make_sim_dataset(options);
  io::DatasetOptions dopt;
  dopt.use_imu = options.robot == "inertial";
  dopt.cameras = options.camera_indices();
  dopt.rate_hz = options.rate_hz;
  return io::open_dataset(*dataset, dopt);
}

Eigen::Matrix<double, 7, 1> pose_vector(const StampedPose& p) {
  Eigen::Matrix<double, 7, 1> v;
  v << p.p_WR, p.q_WR.w(), p.q_WR.x(), p.q_WR.y(), p.q_WR.z();
  return v;
}

// Ctrl-C during a run: Python's signal handlers run only in the main thread with the GIL, so a run checks for them
// after each image (taking the GIL briefly). A pending KeyboardInterrupt (or any exception a handler raised) is kept
// and the run stops; rethrow() raises it once the GIL is back.
class SignalCheck {
 public:
  // With the GIL. Python runs signal handlers in the main thread only: elsewhere there is nothing to check (and no
  // reason to take the GIL after each image).
  SignalCheck() {
    const py::module_ threading = py::module_::import("threading");
    main_thread_ = threading.attr("current_thread")().is(threading.attr("main_thread")());
  }
  // Called without the GIL; true when the run must stop.
  bool interrupted() {
    if (error_) return true;
    if (!main_thread_) return false;
    py::gil_scoped_acquire gil;
    if (PyErr_CheckSignals() != 0) error_.emplace();  // error_already_set fetches the pending exception
    return error_.has_value();
  }
  bool pending() const { return error_.has_value(); }
  // With the GIL: raises what a signal handler raised, if anything.
  void rethrow() {
    if (error_) {
      py::error_already_set e = std::move(*error_);
      error_.reset();
      throw e;
    }
  }

 private:
  bool main_thread_ = false;
  std::optional<py::error_already_set> error_;
};

// A run driven from Python, one processed image at a time (pipeline::ImageSlam).
class Session {
 public:
  Session(const pipeline::ImageSlamOptions& options, const std::optional<std::string>& dataset) {
    options.validate();
    py::gil_scoped_release nogil;
    ds_ = open_run_dataset(options, dataset);
    if (!ds_.source) throw ConfigError("dataset '" + ds_.name + "' has no measurement source");
    slam_ = std::make_unique<pipeline::ImageSlam>(*ds_.source, ds_.rig, ds_.name, dataset ? options.on_selected_cameras() : options);
  }
  // The next processed image as a dict (frame statistics + index + pose), or None at the end of the run.
  py::object step() {
    bool more = false;
    slam::FrameStats stats;
    StampedPose pose;
    long index = 0;
    {
      py::gil_scoped_release nogil;  // then the lock: a thread holding it may wait for the GIL
      std::lock_guard<std::mutex> lock(mu_);
      if (!slam_) throw DataError("the session is finished");
      more = slam_->step();
      const pipeline::ImageSlamResult& r = slam_->result();
      more = more && !r.frames.empty();
      if (more) {
        stats = r.frames.back();
        pose = r.estimate.poses.back();
        index = static_cast<long>(r.frames.size()) - 1;
      }
    }
    if (!more) return py::none();
    py::dict d = frame_dict(stats);
    d["index"] = index;
    d["pose"] = pose_vector(pose);
    return d;
  }
  // The current map's landmark positions (M×3, W).
  Array landmarks() {
    std::vector<Eigen::Vector3d> positions;
    {
      py::gil_scoped_release nogil;
      std::lock_guard<std::mutex> lock(mu_);
      if (!slam_) throw DataError("the session is finished");
      const slam::Map& map = slam_->system().map();
      const Eigen::VectorXd& mean = map.state().mean_vector();
      for (const auto& l : map.landmarks()) positions.push_back(l->position(mean));
    }
    Array out({static_cast<py::ssize_t>(positions.size()), py::ssize_t{3}});
    auto a = out.mutable_unchecked<2>();
    for (std::size_t i = 0; i < positions.size(); ++i) {
      for (int k = 0; k < 3; ++k) a(static_cast<py::ssize_t>(i), k) = positions[i][k];
    }
    return out;
  }
  std::size_t frames() {
    py::gil_scoped_release nogil;
    std::lock_guard<std::mutex> lock(mu_);
    return slam_ ? slam_->result().frames.size() : 0;
  }
  // Runs to the end (if not there yet) and returns the Result; the session is over. Ctrl-C raises KeyboardInterrupt
  // and leaves the session where it stopped (step() or finish() go on from there).
  PyResult finish() {
    pipeline::ImageSlamResult r;
    SignalCheck signals;
    {
      py::gil_scoped_release nogil;
      // Signals are checked without the lock: a handler may call this session.
      bool more = true;
      while (more && !signals.interrupted()) {
        std::lock_guard<std::mutex> lock(mu_);
        if (!slam_) throw DataError("the session is finished");
        more = slam_->step();
      }
      if (!signals.pending()) {
        std::lock_guard<std::mutex> lock(mu_);
        if (!slam_) throw DataError("the session is finished");
        r = slam_->finish();
        slam_.reset();
      }
    }
    signals.rethrow();
    return to_py(r, ds_.ground_truth);
  }

 private:
  io::Dataset ds_;
  std::unique_ptr<pipeline::ImageSlam> slam_;
  std::mutex mu_;  // one call at a time (taken after releasing the GIL)
};

PyResult run(const pipeline::ImageSlamOptions& options, const std::optional<std::string>& dataset,
             const std::optional<py::function>& on_frame) {
  options.validate();
  std::function<void(const pipeline::ImageSlamFrame&)> observer;
  if (on_frame) {
    observer = [&on_frame](const pipeline::ImageSlamFrame& frame) {
      const math::Pose T_WR = frame.map->robots().front()->pose();
      Eigen::Matrix<double, 7, 1> pose;
      pose << T_WR.p, T_WR.q.w(), T_WR.q.x(), T_WR.q.y(), T_WR.q.z();
      py::gil_scoped_acquire gil;
      (*on_frame)(frame.index, to_seconds(frame.t), pose);  // a Python exception propagates and ends the run
    };
  }
  io::Dataset ds;
  pipeline::ImageSlamResult result;
  SignalCheck signals;
  std::atomic<bool> stop{false};
  const auto on_image = [&](int, int) {
    if (signals.interrupted()) stop = true;
  };
  try {
    py::gil_scoped_release nogil;
    ds = open_run_dataset(options, dataset);
    result = pipeline::run_image_slam(ds, dataset ? options.on_selected_cameras() : options, on_image, observer, &stop);
  } catch (const Error&) {
    // A run stopped by Ctrl-C before it could give a result (an inertial robot not started yet) raises the
    // KeyboardInterrupt, not the run's complaint about having been stopped.
    if (!signals.pending()) throw;
  }
  signals.rethrow();  // KeyboardInterrupt: the partial result is dropped, as Python does for any interrupted call
  return to_py(result, ds.ground_truth);
}

py::dict ate(const Array& estimate, const Array& ground_truth, const std::string& align, bool interpolate) {
  eval::EvalOptions eo;
  eo.align = eval::parse_alignment(align);
  eo.with_rpe = false;
  eo.association.interpolate = interpolate;
  const eval::EvalResult r =
      eval::evaluate(to_trajectory(estimate, "estimate"), to_trajectory(ground_truth, "ground_truth"), eo);
  py::dict d;
  d["rmse"] = r.ate.trans_m.rmse;
  d["mean"] = r.ate.trans_m.mean;
  d["max"] = r.ate.trans_m.max;
  d["rot_rmse_deg"] = r.ate.rot_deg.rmse;
  d["scale"] = r.sim3_scale;
  d["matched"] = r.n_matched;
  return d;
}

}  // namespace

PYBIND11_MODULE(rtslam, m) {
  m.doc() = "rtslam: EKF-SLAM on images and IMU (docs/python.md)";
  // numpy's C API loaded now, with the GIL: pybind11 loads it on the first array, and two threads making their first
  // arrays at once (one holding the loader's static guard, the other the GIL) deadlocked.
  py::module_::import("numpy");
  (void)Array(0);

  // Exceptions: most derived first; the message is the library's one line.
  static py::exception<ConfigError> config_error(m, "ConfigError", PyExc_ValueError);
  static py::exception<IoError> io_error(m, "IoError", PyExc_OSError);
  static py::exception<DataError> data_error(m, "DataError", PyExc_RuntimeError);
  static py::exception<InvariantError> invariant_error(m, "InvariantError", PyExc_RuntimeError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const ConfigError& e) {
      config_error(e.what());
    } catch (const IoError& e) {
      io_error(e.what());
    } catch (const DataError& e) {
      data_error(e.what());
    } catch (const InvariantError& e) {
      invariant_error(e.what());
    } catch (const Error& e) {
      PyErr_SetString(PyExc_RuntimeError, e.what());
    }
  });

  py::class_<pipeline::ImageSlamOptions>(m, "Options",
                                          "ImageSlamOptions: the configuration of a run (docs/configuration.md)")
      .def(py::init<>(), "RT-SLAM's defaults (not the simulator's tuned config/sim_mono.yaml: see default_options)")
      .def_readwrite("seed", &pipeline::ImageSlamOptions::seed)
      .def_readwrite("robot", &pipeline::ImageSlamOptions::robot, "constant_velocity | inertial")
      .def_readwrite("consistency", &pipeline::ImageSlamOptions::consistency, "none | oc | fej")
      .def_readwrite("max_frames", &pipeline::ImageSlamOptions::max_frames, "stop after this many images (0: all)")
      .def_readwrite("camera", &pipeline::ImageSlamOptions::camera)
      .def_readwrite("rate_hz", &pipeline::ImageSlamOptions::rate_hz)
      .def_readwrite("sim_preset", &pipeline::ImageSlamOptions::sim_preset, "simulator preset or YAML file")
      .def_readwrite("sim_duration_s", &pipeline::ImageSlamOptions::sim_duration_s, "simulated s (0: the preset's)")
      .def("validate", &pipeline::ImageSlamOptions::validate, "raises ConfigError naming the key and the bound")
      .def("to_yaml", [](const pipeline::ImageSlamOptions& o) { return YAML::Dump(pipeline::to_yaml(o)); },
           "the effective configuration (rtslam run --dump-config)")
      .def("__repr__", [](const pipeline::ImageSlamOptions& o) {
        return "<rtslam.Options robot=" + o.robot + " seed=" + std::to_string(o.seed) + " sim_preset=" + o.sim_preset +
               ">";
      });

  m.def("load_config", &pipeline::load_image_slam_config, py::arg("path"),
        "Options from a YAML file over the defaults; raises IoError/ConfigError naming the file and key.");
  m.def("default_options", &pipeline::default_sim_options,
        "The options of `rtslam run` on the simulator (config/sim_mono.yaml as built).");

  py::class_<PyResult>(m, "Result", "The output of rtslam.run")
      .def_readonly("trajectory", &PyResult::trajectory, "N×8 [t (s), x y z, qw qx qy qz]: T_WR per processed image")
      .def_readonly("timestamps_ns", &PyResult::timestamps_ns, "int64 image times (ns), the trajectory's")
      .def_readonly("landmarks", &PyResult::landmarks, "M×3 positions in W (m) of the final map")
      .def_readonly("frames", &PyResult::frames, "per processed image: a dict of FrameStats (t, matched, time_ms...)")
      .def_readonly("ground_truth", &PyResult::ground_truth, "N×8 like trajectory, or None")
      .def_readonly("resets", &PyResult::resets)
      .def_readonly("frames_lost", &PyResult::frames_lost)
      .def_readonly("frames_diverged", &PyResult::frames_diverged)
      .def_readonly("inertial", &PyResult::inertial)
      .def_readonly("inertial_start", &PyResult::inertial_start, "how the inertial filter started ('' otherwise)")
      .def_readonly("landmarks_created", &PyResult::landmarks_created)
      .def("__repr__", [](const PyResult& r) {
        return "<rtslam.Result poses=" + std::to_string(r.trajectory.shape(0)) +
               " landmarks=" + std::to_string(r.landmarks.shape(0)) + " resets=" + std::to_string(r.resets) + ">";
      });

  m.def("run", &run, py::arg("options"), py::arg("dataset") = py::none(), py::arg("on_frame") = py::none(),
        "Runs image SLAM on dataset 'KIND:PATH' (or 'PATH'), or on the simulator (options.sim_preset) when None.\n"
        "on_frame(index, t_s, pose) is called after each processed image, pose = [x y z qw qx qy qz] of T_WR.");
  py::class_<Session>(m, "Session",
                      "A run stepped from Python: Session(options, dataset=None), then step() until it returns None")
      .def(py::init<const pipeline::ImageSlamOptions&, const std::optional<std::string>&>(), py::arg("options"),
           py::arg("dataset") = py::none())
      .def("step", &Session::step,
           "Feeds the stream until the filter processed one more image; returns that frame's dict (FrameStats, index,\n"
           "pose = [x y z qw qx qy qz]; the latest one when a start replays several images) or None at the end.")
      .def("landmarks", &Session::landmarks, "M×3 positions in W (m) of the current map")
      .def_property_readonly("frames", &Session::frames, "images processed so far")
      .def("finish", &Session::finish, "runs to the end and returns the Result (the session is then over)");

  m.def("ate", &ate, py::arg("estimate"), py::arg("ground_truth"), py::arg("align") = "se3",
        py::arg("interpolate") = true,
        "ATE (m) of two N×8 trajectories after alignment (se3 | sim3 | posyaw | origin | none), the ground truth\n"
        "interpolated at the estimate's times (or nearest within 10 ms): dict(rmse, mean, max, rot_rmse_deg, scale,\n"
        "matched); scale is the Sim(3) Umeyama scale whatever the alignment.");
}
