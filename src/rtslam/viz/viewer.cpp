#include "rtslam/viz/viewer.hpp"

#include <arpa/inet.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <list>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include <Eigen/Eigenvalues>
#include <civetweb.h>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>  // cv::IMWRITE_*
#include <opencv2/imgproc.hpp>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/eval/align.hpp"
#include "rtslam/eval/chi2.hpp"
#include "rtslam/io/codecs.hpp"
#include "rtslam/viz/assets.hpp"
#include "rtslam/viz/history.hpp"
#include "rtslam/viz/latest_queue.hpp"

namespace rtslam::viz {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

void ViewerOptions::validate() const {
  (void)parse_address(address);
  if (queue_frames < 1) throw ConfigError(fmt::format("viewer: queue_frames = {} must be >= 1", queue_frames));
  if (!(max_fps > 0.0) || !std::isfinite(max_fps)) {
    throw ConfigError(fmt::format("viewer: max_fps = {} must be > 0", max_fps));
  }
  if (jpeg_quality < 10 || jpeg_quality > 100) {
    throw ConfigError(fmt::format("viewer: jpeg_quality = {} must be in [10, 100]", jpeg_quality));
  }
  if (max_image_width < 0) throw ConfigError(fmt::format("viewer: max_image_width = {} must be >= 0", max_image_width));
  if (max_history < 100) throw ConfigError(fmt::format("viewer: max_history = {} must be >= 100", max_history));
  if (write_timeout_ms < 100 || write_timeout_ms > 600000) {
    throw ConfigError(fmt::format("viewer: write_timeout_ms = {} must be in [100, 600000]", write_timeout_ms));
  }
  if (eval::parse_alignment(ground_truth_alignment) == eval::Alignment::None) {
    throw ConfigError("viewer: ground_truth_alignment = none: the ground truth must be drawn in the estimate's "
                      "frame (sim3, se3, posyaw or origin)");
  }
  overlay.validate();
}

std::pair<std::string, int> parse_address(const std::string& address) {
  const auto bad = [&](const std::string& why) {
    return ConfigError(fmt::format("viewer address '{}': {} (expected IPv4:PORT, e.g. 127.0.0.1:8080, or PORT)",
                                   address, why));
  };
  if (address.empty()) throw bad("empty");
  if (address.front() == '[') throw bad("IPv6 is not supported (Debian's CivetWeb is built without it)");
  std::string host = "127.0.0.1", port_text = address;
  if (const auto colon = address.rfind(':'); colon != std::string::npos) {
    host = address.substr(0, colon);
    port_text = address.substr(colon + 1);
  }
  if (host == "localhost") host = "127.0.0.1";
  in_addr a{};
  if (inet_pton(AF_INET, host.c_str(), &a) != 1) throw bad(fmt::format("'{}' is not an IPv4 address", host));
  if (port_text.empty() || port_text.size() > 5 ||
      !std::all_of(port_text.begin(), port_text.end(), [](char c) { return c >= '0' && c <= '9'; })) {
    throw bad(fmt::format("'{}' is not a port number", port_text));
  }
  const int port = std::stoi(port_text);
  if (port > 65535) throw bad(fmt::format("port {} is above 65535", port));
  return {host, port};
}

namespace {

// JSON text of a message; a string that is not UTF-8 (a folder or dataset name) becomes U+FFFD rather than an error.
std::string dump_json(const nlohmann::json& j) {
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

constexpr int kMaxClients = 4;                          // pages connected at once (each holds a server thread)
constexpr std::uintmax_t kMaxOverlayBytes = 64u << 20;  // an overlay PNG beyond this is not served

// ---- JSON of the messages (the page's protocol, see web/js/main.js) ---------------------------------------------

json vec3(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
json pose_json(const math::Pose& T) {
  return {{"p", vec3(T.p)}, {"q", {T.q.w(), T.q.x(), T.q.y(), T.q.z()}}};
}

// Band of the mean NIS per observation of k 2-dof observations (99 %): [χ²_0.005(2k) / k, χ²_0.995(2k) / k].
std::pair<double, double> nis_band(int k) {
  static std::mutex mu;
  static std::map<int, std::pair<double, double>> cache;
  std::lock_guard<std::mutex> lock(mu);
  auto it = cache.find(k);
  if (it == cache.end()) {
    const double dof = 2.0 * k;
    it = cache.emplace(k, std::make_pair(eval::chi2_quantile(0.005, dof) / k, eval::chi2_quantile(0.995, dof) / k))
             .first;
  }
  return it->second;
}

std::string history_entry_json(const HistoryEntry& h) {
  json e;
  e["i"] = h.index;
  e["t"] = to_seconds(h.t);
  e["p"] = vec3(h.T_WR.p);
  e["q"] = {h.T_WR.q.w(), h.T_WR.q.x(), h.T_WR.q.y(), h.T_WR.q.z()};
  if (h.cov) e["sp"] = vec3(h.cov->diagonal().head<3>().cwiseMax(0.0).cwiseSqrt());
  if (h.has_stats) {
    const auto& s = h.stats;
    e["n"] = {s.visible, s.searched, s.matched, s.ransac_inliers, s.updated, s.initialized, s.landmarks_in_map};
  }
  if (h.has_timing) e["ms"] = h.stats.time_total_ms;
  if (h.nis.count > 0) {
    e["nis"] = h.nis.sum / h.nis.count;
    const auto [lo, hi] = nis_band(h.nis.count);
    e["nisb"] = {lo, hi};
  }
  if (std::isfinite(h.nees)) e["nees"] = h.nees;
  return dump_json(e);
}

// Landmarks as [id, euclidean, x, y, z, a1x, a1y, a1z, a2..., a3..., flags]: a_k the 3σ principal half-axes of the
// position covariance (longest first, at most 50 m), flags 1 = updated in this frame, 2 = matched, 4 = new.
json landmarks_json(const std::vector<LandmarkReport>& lms, const std::vector<FrameMatch>& matches, int types) {
  std::map<int, int> flags;
  for (const FrameMatch& m : matches) flags[m.landmark_id] |= (m.updated ? 1 : 0) | (m.matched ? 2 : 0);
  json out = json::array();
  for (const LandmarkReport& l : lms) {
    if (!l.p_W.allFinite()) continue;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(0.5 * (l.cov_W + l.cov_W.transpose()));
    json row = {l.id, types ? (l.euclidean ? 1 : 0) : -1, l.p_W.x(), l.p_W.y(), l.p_W.z()};
    for (int k = 2; k >= 0; --k) {
      const double len = std::min(3.0 * std::sqrt(std::max(0.0, es.eigenvalues()[k])), 50.0);
      const Eigen::Vector3d a = es.eigenvectors().col(k) * (std::isfinite(len) ? len : 0.0);
      row.push_back(a.x());
      row.push_back(a.y());
      row.push_back(a.z());
    }
    const auto f = flags.find(l.id);
    row.push_back((f == flags.end() ? 0 : f->second) | (l.created_now ? 4 : 0));
    out.push_back(std::move(row));
  }
  return out;
}

json camera_json(const CameraInfo& c) {
  return {{"width", c.width}, {"height", c.height}, {"fx", c.fx}, {"fy", c.fy}, {"cx", c.cx}, {"cy", c.cy}};
}

// Ground truth for the page: times and positions, at most ~20000 poses (evenly decimated).
json ground_truth_json(const Trajectory& gt) {
  json t = json::array(), p = json::array();
  const std::size_t n = gt.poses.size(), step = std::max<std::size_t>(1, n / 20000);
  for (std::size_t i = 0; i < n; i += step) {
    t.push_back(to_seconds(gt.poses[i].t));
    p.push_back(gt.poses[i].p_WR.x());
    p.push_back(gt.poses[i].p_WR.y());
    p.push_back(gt.poses[i].p_WR.z());
  }
  return {{"t", std::move(t)}, {"p", std::move(p)}};
}

// Lowers the calling thread's scheduling priority (Linux: nice is per thread).
void lower_this_thread_priority() {
  const auto tid = static_cast<id_t>(::syscall(SYS_gettid));
  if (::setpriority(PRIO_PROCESS, tid, 10) != 0) logger("viz")->debug("viewer thread: setpriority failed");
}

std::once_flag g_civetweb_init;
thread_local Viewer::Impl* t_starting = nullptr;  // the viewer whose mg_start runs on this thread (its log messages)

}  // namespace

// ---------------------------------------------------------------------------------------------------------------

class Viewer::Impl {
 public:
  explicit Impl(ViewerOptions o) : opt_(validated(std::move(o))), queue_(static_cast<std::size_t>(opt_.queue_frames)) {
    alignment_ = eval::parse_alignment(opt_.ground_truth_alignment);
    io::codecs::load_plugin();  // the page's JPEGs: a missing plugin is an error now, not a warning per frame later
    start_server();
    worker_ = std::thread([this] { run(); });
  }

  ~Impl() { stop(); }

  void stop() {
    std::lock_guard<std::mutex> stop_lock(stop_mu_);
    if (stopped_) return;
    stopped_ = true;
    stopping_ = true;
    queue_.wake();
    if (worker_.joinable()) worker_.join();
    // The worker hands nothing more to the pages' senders: close the connections (their close handlers, which stop
    // the senders, run inside mg_stop; a sender's write in progress ends at CivetWeb's stop flag).
    if (ctx_ != nullptr) {
      // CivetWeb's listening thread polls its sockets in 2 s steps and looks at the stop flag between them: a
      // connection to our own port ends the step, so that mg_stop returns at once instead of up to 2 s later (every
      // `rtslam run --view` and `rtslam view` ends through here).
      std::atomic<bool> done{false};
      std::thread waker([this, &done] {
        while (!done.load()) {
          poke_listener();
          std::this_thread::sleep_for(std::chrono::milliseconds(20));
        }
      });
      mg_stop(ctx_);
      done = true;
      waker.join();
    }
    ctx_ = nullptr;
  }

  // Opens and closes a TCP connection to the listening port (refused once the socket is closed: harmless).
  void poke_listener() const {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0) return;
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port_));
    inet_pton(AF_INET, host_ == "0.0.0.0" ? "127.0.0.1" : host_.c_str(), &a.sin_addr);
    (void)::connect(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a);
    ::close(fd);
  }

  std::string url() const { return fmt::format("http://{}:{}/", host_ == "0.0.0.0" ? "127.0.0.1" : host_, port_); }
  int port() const { return port_; }

  void set_title(const std::string& t) {
    std::lock_guard<std::mutex> lock(meta_mu_);
    title_ = t;
    ++meta_version_;
    queue_.wake();
  }

  void set_ground_truth(const Trajectory& gt) {
    auto copy = std::make_shared<Trajectory>(gt);
    std::sort(copy->poses.begin(), copy->poses.end(), [](const StampedPose& a, const StampedPose& b) { return a.t < b.t; });
    std::lock_guard<std::mutex> lock(meta_mu_);
    gt_ = std::move(copy);
    ++meta_version_;
    queue_.wake();
  }

  // The filter thread: wait-free (latest_queue.hpp).
  bool push(FrameReport&& r) {
    history_ring_.push(summarize(r));
    return queue_.push(std::move(r));
  }

  void finish() {
    finished_ = true;
    queue_.wake();
  }

  void show_recording(RunRecording rec) {
    auto r = std::make_shared<const RunRecording>(std::move(rec));
    std::lock_guard<std::mutex> lock(meta_mu_);
    recording_ = std::move(r);
    replay_ = true;
    title_ = recording_->title;
    ++meta_version_;
    finished_ = true;
    queue_.wake();
  }

  ViewerStats stats() const {
    ViewerStats s;
    s.pushed = queue_.pushed();
    s.dropped = queue_.dropped();
    s.processed = processed_.load();
    s.frames_sent = frames_sent_.load();
    s.clients = clients_count_.load();
    s.history_dropped = history_ring_.dropped();
    s.pages_cut = pages_cut_.load();
    return s;
  }

 private:
  // One WebSocket message for a page. Its bytes are shared: a frame's JSON and JPEG are made once for every page.
  struct Outgoing {
    int opcode = MG_WEBSOCKET_OPCODE_TEXT;
    std::shared_ptr<const std::string> bytes;
    bool ends_frame = false;  // the last message of a frame: counted in frames_sent once written
  };

  // A connected page. The viewer thread decides what the page lacks and hands it over as one batch; the page's own
  // sender thread writes it. A page that stops reading blocks only its sender (until CivetWeb's write timeout,
  // request_timeout_ms, fails the write and marks it dead), never the viewer thread nor the other pages. While a
  // batch is being written the page is handed nothing new, and its next batch carries all it lacks by then (the
  // history since, the newest frame): what waits for a slow page is bounded by one batch.
  struct Client {
    mg_connection* conn = nullptr;
    std::atomic<int> in_flight{0};      // frames sent and not yet acknowledged by the page
    std::atomic<bool> dead{false};      // a write failed
    // The viewer thread's record of what the page has been handed.
    bool hello_sent = false;
    long meta_version = -1;
    std::size_t history_sent = 0;
    long align_version = -1;
    int frame_sent = -1;                // index of the last frame sent
    bool finished_sent = false;
    Clock::time_point last_frame_time{};
    // The sender: `batch` and the flags under `mu`.
    std::mutex mu;
    std::condition_variable cv;
    std::vector<Outgoing> batch;        // handed over, not yet taken by the sender
    bool writing = false;               // a batch is handed over or being written
    std::atomic<bool> quit{false};      // looked at before each message too: a closing page waits for no batch
    std::thread sender;

    ~Client() { stop_sender(); }
    void stop_sender() {
      {
        std::lock_guard<std::mutex> lock(mu);
        quit = true;
      }
      cv.notify_all();
      if (sender.joinable()) sender.join();
    }
  };

  // The newest frame, ready to send: its JSON and the JPEG of its overlay (empty without an image).
  struct Prepared {
    int index = -1;
    std::shared_ptr<const std::string> json;
    std::shared_ptr<const std::string> jpeg;
  };

  static ViewerOptions validated(ViewerOptions o) {
    o.validate();
    return o;
  }

  // ---- server --------------------------------------------------------------------------------------------------

  void start_server() {
    std::call_once(g_civetweb_init, [] { mg_init_library(MG_FEATURES_WEBSOCKET); });
    const auto [host, port] = parse_address(opt_.address);
    host_ = host;
    if (host_ == "0.0.0.0") logger("viz")->warn("viewer: listening on ALL interfaces (address {})", opt_.address);
    const std::string ports = fmt::format("{}:{}", host, port);
    const std::string timeout = std::to_string(opt_.write_timeout_ms);
    const char* options[] = {"listening_ports", ports.c_str(),
                             "num_threads", "16",  // kMaxClients WebSockets hold one each
                             "request_timeout_ms", timeout.c_str(),
                             "websocket_timeout_ms", "3600000",
                             "enable_keep_alive", "yes",
                             "enable_directory_listing", "no",
                             nullptr};
    mg_callbacks cb{};
    cb.log_message = [](const mg_connection* conn, const char* message) -> int {
      Impl* self = t_starting;
      if (conn != nullptr) {
        if (const mg_context* ctx = mg_get_context(conn)) self = static_cast<Impl*>(mg_get_user_data(ctx));
      }
      if (self != nullptr) {
        std::lock_guard<std::mutex> lock(self->log_mu_);
        self->last_log_ = message;
      } else {
        logger("viz")->debug("civetweb: {}", message);
      }
      return 1;
    };
    t_starting = this;
    ctx_ = mg_start(&cb, this, options);
    t_starting = nullptr;
    if (ctx_ == nullptr) {
      std::lock_guard<std::mutex> lock(log_mu_);
      throw IoError(fmt::format("viewer: cannot listen on {}{}{}", ports, last_log_.empty() ? "" : ": ", last_log_));
    }
    mg_server_port sp[4];
    const int n = mg_get_server_ports(ctx_, 4, sp);
    port_ = n > 0 ? sp[0].port : port;
    mg_set_websocket_handler(ctx_, "/ws", &Impl::ws_connect, &Impl::ws_ready, &Impl::ws_data, &Impl::ws_close, this);
    mg_set_request_handler(ctx_, "**", &Impl::http, this);
    logger("viz")->info("viewer: {}", url());
  }

  static int http(mg_connection* conn, void* cbdata) {
    auto* self = static_cast<Impl*>(cbdata);
    if (!self->host_allowed(conn)) {
      mg_send_http_error(conn, 403, "%s", "this viewer answers to 127.0.0.1 and localhost only");
      return 403;
    }
    try {  // nothing may unwind through CivetWeb's C frames
      return self->handle_http(conn);
    } catch (const std::exception& e) {
      logger("viz")->warn("viewer: request failed: {}", e.what());
      mg_send_http_error(conn, 500, "%s", "internal error");
      return 500;
    }
  }

  int handle_http(mg_connection* conn) {
    const mg_request_info* ri = mg_get_request_info(conn);
    const std::string_view method = ri->request_method ? ri->request_method : "";
    const std::string_view uri = ri->local_uri ? ri->local_uri : "/";
    if (method != "GET" && method != "HEAD") {
      mg_send_http_error(conn, 405, "%s", "only GET");
      return 405;
    }
    const bool head = method == "HEAD";
    const auto send = [&](const char* mime, const void* data, std::size_t size, const char* cache) {
      mg_printf(conn,
                "HTTP/1.1 200 OK\r\nContent-Type: %s\r\nContent-Length: %zu\r\nCache-Control: %s\r\n"
                "X-Content-Type-Options: nosniff\r\n\r\n",
                mime, size, cache);
      if (!head && size > 0) mg_write(conn, data, size);
      return 200;
    };
    if (uri == "/api/status") {
      const std::string body = dump_json(status_json());
      return send("application/json", body.data(), body.size(), "no-store");
    }
    if (uri.rfind("/api/overlay/", 0) == 0) {
      std::shared_ptr<const RunRecording> rec;
      {
        std::lock_guard<std::mutex> lock(meta_mu_);
        rec = recording_;
      }
      int index = -1;
      try {
        index = std::stoi(std::string(uri.substr(std::strlen("/api/overlay/"))));
      } catch (const std::exception&) {
        index = -1;
      }
      const OverlayFrame* f = nullptr;
      if (rec) {
        const auto it = std::lower_bound(rec->overlays.begin(), rec->overlays.end(), index,
                                         [](const OverlayFrame& o, int i) { return o.index < i; });
        if (it != rec->overlays.end() && it->index == index) f = &*it;
      }
      if (f == nullptr) {
        mg_send_http_error(conn, 404, "no overlay %d", index);
        return 404;
      }
      // Only a regular file of the overlays folder (load_run admits bare file names only): not a symbolic link, a
      // device or a FIFO, and not beyond any overlay's size.
      std::error_code ec;
      const auto status = std::filesystem::symlink_status(f->path, ec);
      const auto size = ec ? 0 : std::filesystem::file_size(f->path, ec);
      if (ec || status.type() != std::filesystem::file_type::regular || size > kMaxOverlayBytes) {
        mg_send_http_error(conn, 404, "cannot read overlay %d", index);
        return 404;
      }
      std::ifstream in(f->path, std::ios::binary);
      const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      if (!in && bytes.empty()) {
        mg_send_http_error(conn, 404, "cannot read overlay %d", index);
        return 404;
      }
      return send("image/png", bytes.data(), bytes.size(), "max-age=3600");
    }
    if (const Asset* a = find_asset(uri)) return send(std::string(a->mime).c_str(), a->data, a->size, "no-cache");
    mg_send_http_error(conn, 404, "%s", "not found");
    return 404;
  }

  // "scheme://user@host:port/path" (or a Host header's "host:port") → {host in lower case, port}.
  static std::pair<std::string, std::string> split_host(std::string s) {
    if (const auto scheme = s.find("://"); scheme != std::string::npos) s = s.substr(scheme + 3);
    if (const auto end = s.find_first_of("/?#"); end != std::string::npos) s = s.substr(0, end);
    if (const auto at = s.rfind('@'); at != std::string::npos) s = s.substr(at + 1);
    std::string host = s, port;
    if (!s.empty() && s.front() == '[') {
      const auto close = s.find(']');
      host = s.substr(0, close == std::string::npos ? s.size() : close + 1);
      if (close != std::string::npos && close + 1 < s.size() && s[close + 1] == ':') port = s.substr(close + 2);
    } else if (const auto colon = s.rfind(':'); colon != std::string::npos) {
      host = s.substr(0, colon);
      port = s.substr(colon + 1);
    }
    std::transform(host.begin(), host.end(), host.begin(), [](unsigned char c) { return std::tolower(c); });
    return {host, port};
  }
  // Bound to a loopback address (the default), the viewer answers only requests that name a loopback host: a page of
  // another site whose name was made to resolve to 127.0.0.1 (DNS rebinding) sends that name as Host and is refused.
  // Bound to another address, the user chose to expose it (with a warning): any Host.
  bool loopback_name(const std::string& name) const {
    return name == "127.0.0.1" || name == "localhost" || name == host_;
  }
  bool host_allowed(const mg_connection* conn) const {
    if (host_.rfind("127.", 0) != 0) return true;
    const char* host = mg_get_header(conn, "Host");
    return host == nullptr || loopback_name(split_host(host).first);  // HTTP/1.0 clients may send none; browsers do
  }
  // A page of another origin may not read the run (cross-site WebSocket): the Origin header, when sent, must name
  // this viewer — a loopback name (or the Host header's name when bound beyond loopback) and this port; and a few
  // pages at most (each holds a server thread).
  static int ws_connect(const mg_connection* conn, void* cbdata) {
    const auto* self = static_cast<const Impl*>(cbdata);
    if (!self->host_allowed(conn)) return 1;
    if (self->clients_count_.load() >= kMaxClients) {
      logger("viz")->warn("viewer: WebSocket refused: {} pages are connected already", kMaxClients);
      return 1;
    }
    const char* origin = mg_get_header(conn, "Origin");
    if (origin == nullptr) return 0;
    const char* host = mg_get_header(conn, "Host");
    const auto [o, o_port] = split_host(origin);
    // The page's own address: this port, or the one the Host header names (a tunnel, e.g. ssh -L 9000:...:8080;
    // no port: 80).
    const auto [h, h_port] = host != nullptr ? split_host(host) : std::pair<std::string, std::string>{};
    const auto or80 = [](const std::string& p) { return p.empty() ? std::string("80") : p; };
    const bool this_viewer = self->loopback_name(o) && or80(o_port) == std::to_string(self->port_);
    const bool same_as_host = host != nullptr && o == h && or80(o_port) == or80(h_port);
    if (this_viewer || same_as_host) return 0;
    logger("viz")->warn("viewer: WebSocket from origin '{}' refused (host {})", origin, host ? host : "?");
    return 1;
  }

  // The page limit is enforced here, under the clients' lock: ws_connect's check is only a fast path, and pages
  // that connect at the same moment all pass it. One over the limit is closed at once (1013, "try again later"),
  // without being added; CivetWeb then ends its read loop and calls ws_close, which finds nothing to remove.
  static void ws_ready(mg_connection* conn, void* cbdata) {
    auto* self = static_cast<Impl*>(cbdata);
    auto c = std::make_unique<Client>();
    c->conn = conn;
    std::string refused;  // why, when the page is not added
    {
      std::lock_guard<std::mutex> lock(self->clients_mu_);
      if (self->clients_.size() >= static_cast<std::size_t>(kMaxClients)) {
        refused = fmt::format("{} pages are connected already", kMaxClients);
      } else {
        try {  // nothing may unwind through CivetWeb's C frames
          Client* added = c.get();
          added->sender = std::thread([self, added] { self->send_loop(*added); });
          self->clients_.push_back(std::move(c));
          self->clients_count_ = static_cast<int>(self->clients_.size());
          mg_set_user_connection_data(conn, added);
        } catch (const std::exception& e) {
          refused = e.what();
        }
      }
    }
    if (!refused.empty()) {
      logger("viz")->warn("viewer: WebSocket refused: {}", refused);
      const char try_again_later[2] = {0x03, static_cast<char>(0xF5)};  // close status 1013, big-endian
      mg_websocket_write(conn, MG_WEBSOCKET_OPCODE_CONNECTION_CLOSE, try_again_later, sizeof try_again_later);
      return;
    }
    self->queue_.wake();
  }

  // The page acknowledges each frame it has shown ("ack"); anything else is ignored. Runs on CivetWeb's thread:
  // touches only the client's atomics. A page whose stream a failed write has cut (it stopped reading for
  // `write_timeout_ms`) is closed at its next message (the page pings every 5 s): it reconnects and starts afresh
  // instead of showing a frozen run while holding one of the pages' places.
  static int ws_data(mg_connection* conn, int bits, char* data, std::size_t len, void* cbdata) {
    auto* self = static_cast<Impl*>(cbdata);
    const int opcode = bits & 0x0f;
    if (opcode == MG_WEBSOCKET_OPCODE_CONNECTION_CLOSE) return 0;
    auto* c = static_cast<Client*>(mg_get_user_connection_data(conn));
    if (c == nullptr) return 1;
    if (c->dead) return 0;
    if (opcode == MG_WEBSOCKET_OPCODE_TEXT && len >= 3 && std::string_view(data, 3) == "ack") {
      int v = c->in_flight.load();
      while (v > 0 && !c->in_flight.compare_exchange_weak(v, v - 1)) {
      }
      if (v > 0 && v <= 2) self->queue_.wake();  // room for a frame again (a flood of acks wakes nothing)
    }
    return 1;
  }

  // CivetWeb's connection thread, once the page's connection has ended: the page leaves the list, then its sender
  // is stopped (outside the clients' lock: a write in progress fails or ends first).
  static void ws_close(const mg_connection* conn, void* cbdata) {
    auto* self = static_cast<Impl*>(cbdata);
    std::unique_ptr<Client> gone;
    {
      std::lock_guard<std::mutex> lock(self->clients_mu_);
      const auto it = std::find_if(self->clients_.begin(), self->clients_.end(),
                                   [&](const std::unique_ptr<Client>& c) { return c->conn == conn; });
      if (it != self->clients_.end()) {
        gone = std::move(*it);
        self->clients_.erase(it);
      }
      self->clients_count_ = static_cast<int>(self->clients_.size());
    }
    if (gone) gone->stop_sender();
  }

  // A page's sender thread: writes each batch handed over, in order, and tells the viewer thread when it is done.
  void send_loop(Client& c) {
    if (opt_.lower_priority) lower_this_thread_priority();
    std::vector<Outgoing> todo;
    std::unique_lock<std::mutex> lock(c.mu);
    for (;;) {
      c.cv.wait(lock, [&] { return c.quit || !c.batch.empty(); });
      if (c.quit) return;
      todo.swap(c.batch);
      lock.unlock();
      for (const Outgoing& m : todo) {
        if (c.dead || c.quit) break;
        // The message's bytes written (the header's for an empty one); fewer after a timeout: the stream is cut.
        const auto t0 = Clock::now();
        const int n = mg_websocket_write(c.conn, m.opcode, m.bytes->data(), m.bytes->size());
        if (n <= 0 || (!m.bytes->empty() && static_cast<std::size_t>(n) != m.bytes->size())) {
          if (!c.quit && !stopping_) {  // (not a page closing, nor the server stopping)
            ++pages_cut_;
            if (Clock::now() - t0 >= std::chrono::milliseconds(opt_.write_timeout_ms)) {
              logger("viz")->warn("viewer: a page took no data for {} ms: cut off (it reconnects at its next message)",
                                  opt_.write_timeout_ms);
            } else {
              logger("viz")->debug("viewer: a page's connection broke during a write");
            }
          }
          c.dead = true;
          break;
        }
        if (m.ends_frame) ++frames_sent_;
      }
      todo.clear();
      lock.lock();
      c.writing = false;
      queue_.wake();  // the viewer thread may have more for this page by now
    }
  }

  json status_json() const {
    const ViewerStats s = stats();
    std::lock_guard<std::mutex> lock(status_mu_);
    return {{"mode", replay_.load() ? "replay" : "live"}, {"pushed", s.pushed},       {"dropped", s.dropped},
            {"processed", s.processed},                      {"frames_sent", s.frames_sent}, {"clients", s.clients},
            {"finished", finished_.load()},                   {"latest_frame", status_latest_frame_},
            {"latest_landmarks", status_latest_landmarks_},   {"history", status_history_},
            {"history_thinned", status_history_thinned_}, {"pages_cut", s.pages_cut}};
  }

  // ---- the viewer thread ---------------------------------------------------------------------------------------

  void run() {
    if (opt_.lower_priority) lower_this_thread_priority();
    const auto frame_period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / opt_.max_fps));
    auto wait = std::chrono::milliseconds(100);
    std::uint32_t wakes = queue_.wakes();
    while (!stopping_) {
      std::optional<FrameReport> r = queue_.pop_for(wait, wakes);
      wakes = queue_.wakes();  // a page's sender or ack ringing from here on ends the next wait at once
      if (stopping_) break;
      while (r) {
        latest_ = std::move(*r);
        ++processed_;
        r = queue_.try_pop();
      }
      try {
        update_meta();
        ingest_history();
        refit_alignment();
        wait = sync_clients(frame_period);
      } catch (const std::exception& e) {
        // Never let the viewer take the run down: say it once per kind and go on.
        logger("viz")->warn("viewer: {}", e.what());
        wait = std::chrono::milliseconds(100);
      }
    }
  }

  void update_meta() {
    std::lock_guard<std::mutex> lock(meta_mu_);
    if (meta_version_ == meta_seen_) return;
    meta_seen_ = meta_version_;
    title_seen_ = title_;
    if (recording_ && !recording_seen_) {
      recording_seen_ = recording_;
      recording_mode_ = true;
      history_ = recording_seen_->history;
      history_json_.clear();
      for (const auto& h : history_) history_json_.push_back(history_entry_json(h));
      gt_seen_ = recording_seen_->ground_truth ? std::make_shared<Trajectory>(*recording_seen_->ground_truth) : nullptr;
      gt_json_ = gt_seen_ ? dump_json(ground_truth_json(*gt_seen_)) : "null";
      fit_history_size_ = 0;
      {
        std::lock_guard<std::mutex> slock(status_mu_);
        status_history_ = history_.size();
        status_latest_landmarks_ = recording_seen_->map.size();
        status_latest_frame_ = history_.empty() ? -1 : history_.back().index;
      }
    } else if (gt_ != gt_seen_) {
      gt_seen_ = gt_;
      gt_json_ = gt_seen_ ? dump_json(ground_truth_json(*gt_seen_)) : "null";
      nees_.reset();
      if (gt_seen_) {
        nees_.emplace(*gt_seen_);
        // NEES of the frames already recorded.
        for (std::size_t i = 0; i < history_.size(); ++i) {
          history_[i].nees = nees_->nees(history_[i]);
          history_json_[i] = history_entry_json(history_[i]);
        }
        history_rewritten_ = true;
      }
      fit_history_size_ = 0;
    }
  }

  void ingest_history() {
    if (recording_mode_) return;
    history_ring_.drain(swap_history_);
    for (HistoryEntry& h : swap_history_) {
      if (nees_) h.nees = nees_->nees(h);
      history_json_.push_back(history_entry_json(h));
      history_.push_back(std::move(h));
    }
    swap_history_.clear();
    // Past the bound (however many records one drain brought), thinned to half of it: a re-send to the pages then
    // comes once per max_history / 2 frames, not with every frame.
    if (history_.size() > static_cast<std::size_t>(opt_.max_history)) {
      while (history_.size() > static_cast<std::size_t>(opt_.max_history) / 2) thin_history();
    }
    std::lock_guard<std::mutex> slock(status_mu_);
    status_history_ = history_.size();
    status_history_thinned_ = history_thinned_;
    if (latest_) {
      status_latest_frame_ = latest_->index;
      status_latest_landmarks_ = latest_->landmarks.size();
    }
  }

  // A live run of hours (about 1 KB a record, 100 MB an hour at 30 Hz): the older half of the record keeps every
  // other entry, the newer half all; the pages get the thinned record anew (hello), the plots still span the run.
  void thin_history() {
    const std::size_t old_half = history_.size() / 2;
    std::size_t kept = 0;
    for (std::size_t i = 0; i < history_.size(); ++i) {
      if (i < old_half && i % 2 == 1) continue;
      if (kept != i) {
        history_[kept] = std::move(history_[i]);
        history_json_[kept] = std::move(history_json_[i]);
      }
      ++kept;
    }
    history_.resize(kept);
    history_json_.resize(kept);
    ++history_thinned_;
    history_rewritten_ = true;
    fit_history_size_ = 0;
  }

  // The ground truth in the estimate's frame: S maps ground-truth points onto the estimate (gt' = S ∘ gt), fitted
  // on the poses associated so far (at most once a second while the run goes on); first-pose alignment until the
  // chosen method has enough (non-degenerate) poses.
  void refit_alignment() {
    if (!gt_seen_ || history_.empty()) return;
    if (history_.size() == fit_history_size_) return;
    const auto now = Clock::now();
    if (!recording_mode_ && fit_history_size_ > 0 && now - last_fit_ < std::chrono::seconds(1) && !finished_) return;
    last_fit_ = now;
    fit_history_size_ = history_.size();
    Trajectory est, gt;
    const NeesTracker finder(*gt_seen_);
    for (const HistoryEntry& h : history_) {
      const StampedPose* g = finder.nearest(h.t);
      if (g == nullptr) continue;
      StampedPose e;
      e.t = h.t;
      e.p_WR = h.T_WR.p;
      e.q_WR = h.T_WR.q;
      est.poses.push_back(e);
      gt.poses.push_back(*g);
    }
    if (est.poses.empty()) return;
    eval::Sim3 S;
    std::string method = eval::to_string(alignment_);
    try {
      S = eval::compute_alignment(gt, est, alignment_);
    } catch (const Error&) {
      S = eval::compute_alignment(gt, est, eval::Alignment::Origin);
      method = "origin";
    }
    json m = {{"type", "align"}, {"method", method}, {"s", S.s}, {"t", vec3(S.t)}};
    json R = json::array();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) R.push_back(S.R(i, j));
    m["R"] = std::move(R);
    align_json_ = dump_json(m);
    ++align_version_;
  }

  void prepare_latest() {
    if (!latest_ || (prepared_ && prepared_->index == latest_->index)) return;
    const FrameReport& r = *latest_;
    Prepared p;
    p.index = r.index;
    std::vector<unsigned char> jpeg;
    if (!r.image.empty()) {
      cv::Mat img = draw_overlay(r, opt_.overlay);
      if (opt_.max_image_width > 0 && img.cols > opt_.max_image_width) {
        const double s = static_cast<double>(opt_.max_image_width) / img.cols;
        cv::resize(img, img, cv::Size(), s, s, cv::INTER_AREA);
      }
      io::codecs::imencode(".jpg", img, jpeg, {cv::IMWRITE_JPEG_QUALITY, opt_.jpeg_quality});
      if (!jpeg.empty()) p.jpeg = std::make_shared<const std::string>(jpeg.begin(), jpeg.end());
    }
    json f = {{"type", "frame"},
              {"i", r.index},
              {"t", to_seconds(r.t)},
              {"T_WR", pose_json(r.T_WR)},
              {"T_WS", pose_json(r.T_WS)},
              {"camera", camera_json(r.camera)},
              {"landmarks", landmarks_json(r.landmarks, r.matches, 1)},
              {"n", {r.stats.visible, r.stats.searched, r.stats.matched, r.stats.ransac_inliers, r.stats.updated,
                     r.stats.initialized, static_cast<int>(r.landmarks.size())}},
              {"image", jpeg.size()}};
    p.json = std::make_shared<const std::string>(dump_json(f));
    prepared_ = std::move(p);
  }

  std::string hello_json() const {
    json h = {{"type", "hello"},
              {"mode", recording_mode_ ? "replay" : "live"},
              {"title", title_seen_},
              {"three", three_js_bundled()},
              {"finished", finished_.load()},
              {"nees_band", {eval::chi2_quantile(0.005, 6.0), eval::chi2_quantile(0.995, 6.0)}},
              {"gt", json::parse(gt_json_)}};
    if (recording_seen_) {
      const RunRecording& rec = *recording_seen_;
      json ov = json::array();
      for (const OverlayFrame& o : rec.overlays) ov.push_back({o.index, to_seconds(o.t)});
      h["overlays"] = std::move(ov);
      h["summary"] = rec.summary;
      h["camera"] = camera_json(rec.camera);
      h["map_types_known"] = rec.map_types_known;
      h["dir"] = rec.dir;
    }
    return dump_json(h);
  }

  // The final map of a replay, as a frame without image.
  std::string replay_map_json() const {
    const RunRecording& rec = *recording_seen_;
    json f = {{"type", "frame"},
              {"final", true},
              {"i", rec.history.empty() ? -1 : rec.history.back().index},
              {"t", rec.history.empty() ? 0.0 : to_seconds(rec.history.back().t)},
              {"landmarks", landmarks_json(rec.map, {}, rec.map_types_known ? 1 : 0)},
              {"image", 0}};
    if (!rec.history.empty()) f["T_WR"] = pose_json(rec.history.back().T_WR);
    return dump_json(f);
  }

  static Outgoing text(std::string s) {
    return {MG_WEBSOCKET_OPCODE_TEXT, std::make_shared<const std::string>(std::move(s)), false};
  }

  // Hands every page that is not busy what it lacks (its sender writes it); returns how long the worker may sleep.
  std::chrono::milliseconds sync_clients(Clock::duration frame_period) {
    std::lock_guard<std::mutex> lock(clients_mu_);
    if (clients_.empty()) return std::chrono::milliseconds(100);
    const auto now = Clock::now();
    // push() does not wake this thread (latest_queue.hpp): with browsers connected it polls at their frame rate.
    auto next_due = now + frame_period;
    if (history_rewritten_) {
      for (auto& cp : clients_) cp->hello_sent = false;  // a page busy now gets its hello with its next batch
      history_rewritten_ = false;
    }
    std::vector<Outgoing> out;
    std::shared_ptr<const std::string> hello;  // made once for the pages that need it (the ground truth: megabytes)
    for (auto& cp : clients_) {
      Client& c = *cp;
      if (c.dead) continue;
      {
        std::lock_guard<std::mutex> busy(c.mu);
        if (c.writing) continue;  // its sender wakes this thread when done
      }
      out.clear();
      if (!c.hello_sent || c.meta_version != meta_seen_) {
        // (Re)start: the page resets its state on hello.
        if (!hello) hello = std::make_shared<const std::string>(hello_json());
        out.push_back({MG_WEBSOCKET_OPCODE_TEXT, hello, false});
        c.hello_sent = true;
        c.meta_version = meta_seen_;
        c.history_sent = 0;
        c.align_version = -1;
        c.frame_sent = -1;
        c.finished_sent = false;
        c.in_flight = 0;
        if (recording_mode_) out.push_back(text(replay_map_json()));
      }
      if (c.history_sent < history_json_.size()) {
        std::string m = R"({"type":"history","entries":[)";
        for (std::size_t i = c.history_sent; i < history_json_.size(); ++i) {
          if (i > c.history_sent) m += ',';
          m += history_json_[i];
        }
        m += "]}";
        out.push_back(text(std::move(m)));
        c.history_sent = history_json_.size();
      }
      if (!align_json_.empty() && c.align_version != align_version_) {
        out.push_back(text(align_json_));
        c.align_version = align_version_;
      }
      if (!recording_mode_ && latest_ && c.frame_sent != latest_->index) {
        const auto due = c.last_frame_time + frame_period;
        if (c.in_flight.load() >= 2 && now - c.last_frame_time < std::chrono::seconds(5)) {
          // The page has not shown the last two frames yet: skip (it gets the newest when it acknowledges).
        } else if (due > now) {
          next_due = std::min(next_due, due);
        } else {
          prepare_latest();
          out.push_back({MG_WEBSOCKET_OPCODE_TEXT, prepared_->json, !prepared_->jpeg});
          if (prepared_->jpeg) out.push_back({MG_WEBSOCKET_OPCODE_BINARY, prepared_->jpeg, true});
          c.frame_sent = latest_->index;
          c.last_frame_time = now;
          ++c.in_flight;
        }
      }
      if (finished_ && !c.finished_sent && (!latest_ || c.frame_sent == latest_->index || recording_mode_)) {
        const json s = {{"type", "status"}, {"finished", true}, {"pushed", queue_.pushed()}, {"dropped", queue_.dropped()}};
        out.push_back(text(dump_json(s)));
        c.finished_sent = true;
      }
      if (out.empty()) continue;
      {
        std::lock_guard<std::mutex> hand(c.mu);
        c.batch.swap(out);
        c.writing = true;
      }
      c.cv.notify_one();
    }
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(next_due - now);
    return std::clamp(ms, std::chrono::milliseconds(1), std::chrono::milliseconds(100));
  }

  ViewerOptions opt_;
  eval::Alignment alignment_ = eval::Alignment::Sim3;
  LatestQueue<FrameReport> queue_;

  // Filled by push() (filter thread), taken by the worker: 4096 frames of slack (the worker drains it at least
  // every 100 ms).
  SpscRing<HistoryEntry> history_ring_{4096};

  // Set by the API, read by the worker.
  std::mutex meta_mu_;
  long meta_version_ = 0;
  std::string title_;
  std::shared_ptr<const Trajectory> gt_;
  std::shared_ptr<const RunRecording> recording_;
  std::atomic<bool> finished_{false};
  std::atomic<bool> replay_{false};

  // Worker-only state.
  long meta_seen_ = -1;
  std::string title_seen_;
  std::shared_ptr<const Trajectory> gt_seen_;
  std::shared_ptr<const RunRecording> recording_seen_;
  bool recording_mode_ = false;
  std::string gt_json_ = "null";
  std::optional<NeesTracker> nees_;
  std::vector<HistoryEntry> swap_history_;
  std::vector<HistoryEntry> history_;
  std::vector<std::string> history_json_;
  bool history_rewritten_ = false;
  long history_thinned_ = 0;  // times the record was thinned (thin_history)
  std::optional<FrameReport> latest_;
  std::optional<Prepared> prepared_;
  std::size_t fit_history_size_ = 0;
  Clock::time_point last_fit_{};
  std::string align_json_;
  long align_version_ = 0;

  // Status for /api/status (HTTP threads).
  mutable std::mutex status_mu_;
  int status_latest_frame_ = -1;
  std::size_t status_latest_landmarks_ = 0;
  std::size_t status_history_ = 0;
  long status_history_thinned_ = 0;

  std::atomic<long> processed_{0};
  std::atomic<long> frames_sent_{0};
  std::atomic<long> pages_cut_{0};
  std::atomic<int> clients_count_{0};

  std::mutex clients_mu_;
  std::list<std::unique_ptr<Client>> clients_;

  mg_context* ctx_ = nullptr;
  std::string host_;
  int port_ = 0;
  std::mutex log_mu_;
  std::string last_log_;

  std::thread worker_;
  std::atomic<bool> stopping_{false};
  std::mutex stop_mu_;
  bool stopped_ = false;
};

// ---------------------------------------------------------------------------------------------------------------

Viewer::Viewer(ViewerOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {}
Viewer::~Viewer() = default;
std::string Viewer::url() const { return impl_->url(); }
int Viewer::port() const { return impl_->port(); }
void Viewer::set_title(const std::string& title) { impl_->set_title(title); }
void Viewer::set_ground_truth(const Trajectory& ground_truth) { impl_->set_ground_truth(ground_truth); }
bool Viewer::push(FrameReport report) { return impl_->push(std::move(report)); }
void Viewer::finish() { impl_->finish(); }
void Viewer::show_recording(RunRecording recording) { impl_->show_recording(std::move(recording)); }
ViewerStats Viewer::stats() const { return impl_->stats(); }
void Viewer::stop() { impl_->stop(); }

}  // namespace rtslam::viz
