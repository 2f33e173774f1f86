// The viewer's server on loopback: the page and its assets over HTTP, frames over WebSocket (JSON + JPEG), the
// history for late clients, slow clients, the Origin check, addresses, and the replay of a run folder.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <civetweb.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "rtslam/core/error.hpp"
#include "rtslam/eval/associate.hpp"
#include "rtslam/eval/nees.hpp"
#include "rtslam/io/trajectory_io.hpp"
#include "rtslam/io/writers.hpp"
#include "rtslam/viz/assets.hpp"
#include "rtslam/viz/replay.hpp"
#include "rtslam/viz/viewer.hpp"
#include "viz/viz_test_utils.hpp"

namespace {

namespace fs = std::filesystem;
using namespace rtslam;
using namespace rtslam::viz;
using nlohmann::json;
using namespace std::chrono_literals;

struct HttpResponse {
  int status = 0;
  std::string content_type;
  std::string body;
};

HttpResponse http_get(int port, const std::string& path, const std::string& host = "127.0.0.1") {
  char err[256] = {};
  HttpResponse r;
  mg_connection* c = mg_download("127.0.0.1", port, 0, err, sizeof err, "GET %s HTTP/1.0\r\nHost: %s\r\n\r\n",
                                 path.c_str(), host.c_str());
  if (c == nullptr) {
    ADD_FAILURE() << "GET " << path << ": " << err;
    return r;
  }
  const mg_response_info* ri = mg_get_response_info(c);
  r.status = ri->status_code;
  for (int i = 0; i < ri->num_headers; ++i) {
    if (strcasecmp(ri->http_headers[i].name, "Content-Type") == 0) r.content_type = ri->http_headers[i].value;
  }
  char buf[65536];
  int n = 0;
  while ((n = mg_read(c, buf, sizeof buf)) > 0) r.body.append(buf, static_cast<std::size_t>(n));
  mg_close_connection(c);
  return r;
}

// A WebSocket client (CivetWeb's) that records every message.
class WsClient {
 public:
  WsClient(int port, const char* origin = nullptr) {
    char err[256] = {};
    const std::string o = origin ? origin : "http://127.0.0.1:" + std::to_string(port);
    conn_ = mg_connect_websocket_client("127.0.0.1", port, 0, err, sizeof err, "/ws", o.c_str(), &WsClient::on_data,
                                        &WsClient::on_close, this);
    error_ = err;
  }
  ~WsClient() {
    if (conn_ != nullptr) mg_close_connection(conn_);
  }
  bool connected() const { return conn_ != nullptr; }
  const std::string& error() const { return error_; }
  void send(const std::string& text) {
    mg_websocket_client_write(conn_, MG_WEBSOCKET_OPCODE_TEXT, text.data(), text.size());
  }
  // Waits until `pred(messages)` holds or the timeout passes.
  template <class Pred>
  bool wait_for(Pred pred, std::chrono::seconds timeout = 20s) {
    std::unique_lock<std::mutex> lock(mu_);
    return cv_.wait_for(lock, timeout, [&] { return pred(messages_) || closed_; }) && pred(messages_);
  }
  struct Message {
    bool binary = false;
    std::string data;
    json as_json() const { return json::parse(data); }
  };
  std::vector<Message> messages() {
    std::lock_guard<std::mutex> lock(mu_);
    return messages_;
  }
  bool closed() {
    std::lock_guard<std::mutex> lock(mu_);
    return closed_;
  }
  static std::size_t count_type(const std::vector<Message>& ms, const std::string& type) {
    std::size_t n = 0;
    for (const auto& m : ms) n += !m.binary && m.as_json().value("type", "") == type ? 1 : 0;
    return n;
  }

 private:
  static int on_data(mg_connection*, int bits, char* data, std::size_t len, void* user) {
    auto* self = static_cast<WsClient*>(user);
    const int opcode = bits & 0xf;
    if (opcode != MG_WEBSOCKET_OPCODE_TEXT && opcode != MG_WEBSOCKET_OPCODE_BINARY) return 1;
    {
      std::lock_guard<std::mutex> lock(self->mu_);
      self->messages_.push_back({opcode == MG_WEBSOCKET_OPCODE_BINARY, std::string(data, len)});
    }
    self->cv_.notify_all();
    return 1;
  }
  static void on_close(const mg_connection*, void* user) {
    auto* self = static_cast<WsClient*>(user);
    {
      std::lock_guard<std::mutex> lock(self->mu_);
      self->closed_ = true;
    }
    self->cv_.notify_all();
  }
  mg_connection* conn_ = nullptr;
  std::string error_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::vector<Message> messages_;
  bool closed_ = false;
};

FrameReport frame(int index, int landmarks = 5) {
  FrameReport r = test::blank_report(160, 120);
  r.index = index;
  r.t = 1'000'000'000 + index * 50'000'000LL;
  r.T_WR.p = Eigen::Vector3d(0.01 * index, 0, 0);
  r.T_WS = r.T_WR;
  r.cov_pose = Eigen::Matrix<double, 6, 6>::Identity() * 1e-4;
  for (int i = 0; i < landmarks; ++i) {
    LandmarkReport l;
    l.id = i;
    l.euclidean = i % 2 == 0;
    l.p_W = Eigen::Vector3d(i, 1, 2);
    l.cov_W = Eigen::Vector3d(0.04, 0.01, 0.0025).asDiagonal();  // σ 0.2, 0.1, 0.05 m
    r.landmarks.push_back(l);
  }
  FrameMatch m;
  m.landmark_id = 0;
  m.h = Eigen::Vector2d(80, 60);
  m.S = test::covariance(5, 3, 0.2);
  m.z = Eigen::Vector2d(81, 60.5);
  m.searched = m.matched = m.updated = m.ransac_inlier = true;
  r.matches.push_back(m);
  r.stats.visible = r.stats.searched = r.stats.matched = r.stats.updated = 1;
  return r;
}

ViewerOptions loopback() {
  ViewerOptions o;
  o.address = "127.0.0.1:0";
  o.max_fps = 200.0;
  return o;
}

TEST(Viewer, ServesThePageAndItsAssetsOnLoopback) {
  Viewer v(loopback());
  ASSERT_GT(v.port(), 0);
  EXPECT_EQ(v.url(), "http://127.0.0.1:" + std::to_string(v.port()) + "/");
  const HttpResponse page = http_get(v.port(), "/");
  EXPECT_EQ(page.status, 200);
  EXPECT_NE(page.content_type.find("text/html"), std::string::npos);
  EXPECT_NE(page.body.find("rtslam viewer"), std::string::npos);
  const HttpResponse js = http_get(v.port(), "/js/main.js");
  EXPECT_EQ(js.status, 200);
  EXPECT_NE(js.content_type.find("javascript"), std::string::npos);
  EXPECT_EQ(js.body.size(), find_asset("/js/main.js")->size);
  if (three_js_bundled()) {
    const HttpResponse three = http_get(v.port(), "/vendor/three/three.module.js");
    EXPECT_EQ(three.status, 200);
    EXPECT_GT(three.body.size(), 100000u);
    EXPECT_NE(three.body.find("Three.js Authors"), std::string::npos);
  }
  EXPECT_EQ(http_get(v.port(), "/no/such/file").status, 404);
  const HttpResponse status = http_get(v.port(), "/api/status");
  EXPECT_EQ(status.status, 200);
  EXPECT_EQ(json::parse(status.body)["mode"], "live");
}

TEST(Viewer, AWebSocketClientReceivesAFrameWithItsJpeg) {
  Viewer v(loopback());
  WsClient ws(v.port());
  ASSERT_TRUE(ws.connected()) << ws.error();
  ASSERT_TRUE(ws.wait_for([](const auto& ms) { return WsClient::count_type(ms, "hello") == 1; }));
  v.push(frame(0, 7));
  ASSERT_TRUE(ws.wait_for([](const auto& ms) { return !ms.empty() && ms.back().binary; }));
  const auto ms = ws.messages();
  const json hello = ms.front().as_json();
  EXPECT_EQ(hello["mode"], "live");
  EXPECT_EQ(hello["three"], three_js_bundled());
  // history (the frame's record), then the frame, then its JPEG.
  const auto& img = ms.back();
  const json f = ms[ms.size() - 2].as_json();
  EXPECT_EQ(f["type"], "frame");
  EXPECT_EQ(f["i"], 0);
  EXPECT_EQ(f["landmarks"].size(), 7u);
  EXPECT_EQ(f["landmarks"][0][1], 1) << "landmark 0 is Euclidean";
  EXPECT_EQ(f["landmarks"][1][1], 0) << "landmark 1 is AHP";
  EXPECT_EQ(f["landmarks"][0][14], 3) << "landmark 0 was matched and updated";
  EXPECT_NEAR(std::abs(f["landmarks"][0][5].get<double>()), 0.6, 1e-9) << "longest 3σ half-axis (σ = 0.2 m along x)";
  EXPECT_EQ(f["image"], img.data.size());
  ASSERT_GT(img.data.size(), 4u);
  EXPECT_EQ(static_cast<unsigned char>(img.data[0]), 0xFF);
  EXPECT_EQ(static_cast<unsigned char>(img.data[1]), 0xD8) << "a JPEG";
  EXPECT_EQ(WsClient::count_type(ms, "history"), 1u);
  v.stop();
  EXPECT_TRUE(ws.wait_for([](const auto&) { return false; }, 5s) || ws.closed()) << "stop() closes the connection";
}

TEST(Viewer, ALateClientGetsTheWholeHistoryAndTheLatestFrame) {
  Viewer v(loopback());
  for (int i = 0; i < 50; ++i) v.push(frame(i));
  v.finish();
  // Let the viewer thread take all of them in (it polls; under sanitizers it is slow).
  const auto taken_in = [&v] {
    const ViewerStats s = v.stats();
    return s.dropped + s.processed == 50;
  };
  for (int k = 0; k < 1000 && !taken_in(); ++k) std::this_thread::sleep_for(10ms);
  ASSERT_TRUE(taken_in()) << "the viewer thread did not take the 50 frames in within 10 s";
  WsClient ws(v.port());
  ASSERT_TRUE(ws.connected()) << ws.error();
  ASSERT_TRUE(ws.wait_for([](const auto& ms) { return WsClient::count_type(ms, "status") == 1; }));
  std::size_t entries = 0;
  int last_frame = -1;
  for (const auto& m : ws.messages()) {
    if (m.binary) continue;
    const json j = m.as_json();
    if (j["type"] == "history") entries += j["entries"].size();
    if (j["type"] == "frame") last_frame = j["i"];
  }
  EXPECT_EQ(entries, 50u) << "every frame's record, dropped reports included";
  EXPECT_EQ(last_frame, 49);
  const ViewerStats s = v.stats();
  EXPECT_EQ(s.pushed, 50);
  EXPECT_EQ(s.dropped + s.processed, 50);
}

TEST(Viewer, ALongLiveRunKeepsABoundedThinnedHistory) {
  // A live camera for hours: the record grew by about 1 KB a frame without bound. With room for 100 records, 400
  // frames leave at most 100, spanning the whole run in time order (older parts at a lower rate).
  ViewerOptions o = loopback();
  o.max_history = 100;
  Viewer v(o);
  for (int i = 0; i < 400; ++i) v.push(frame(i));
  v.finish();
  const auto taken_in = [&v] {
    const ViewerStats s = v.stats();
    return s.dropped + s.processed == 400;
  };
  for (int k = 0; k < 1000 && !taken_in(); ++k) std::this_thread::sleep_for(10ms);
  ASSERT_TRUE(taken_in());
  // The record is ingested after the frames are counted: wait until the status shows the last one.
  json status;
  for (int k = 0; k < 1000; ++k) {
    status = json::parse(http_get(v.port(), "/api/status").body);
    if (status["latest_frame"] == 399) break;
    std::this_thread::sleep_for(10ms);
  }
  ASSERT_EQ(status["latest_frame"], 399);
  EXPECT_LE(status["history"].get<int>(), 100);
  EXPECT_GT(status["history"].get<int>(), 25);
  EXPECT_GT(status["history_thinned"].get<int>(), 0);
  WsClient ws(v.port());
  ASSERT_TRUE(ws.connected()) << ws.error();
  ASSERT_TRUE(ws.wait_for([](const auto& ms) { return WsClient::count_type(ms, "status") == 1; }));
  std::vector<int> indices;
  for (const auto& m : ws.messages()) {
    if (m.binary) continue;
    const json j = m.as_json();
    if (j["type"] == "hello") indices.clear();  // a restart: the record sent anew
    if (j["type"] == "history") {
      for (const auto& e : j["entries"]) indices.push_back(e["i"].get<int>());
    }
  }
  ASSERT_EQ(static_cast<int>(indices.size()), status["history"].get<int>());
  EXPECT_EQ(indices.front(), 0);
  EXPECT_EQ(indices.back(), 399);
  EXPECT_TRUE(std::is_sorted(indices.begin(), indices.end()));
  EXPECT_THROW(
      [] {
        ViewerOptions bad = loopback();
        bad.max_history = 10;
        bad.validate();
      }(),
      ConfigError);
}

TEST(Viewer, PushNeverWaitsForABrowserThatDoesNotKeepUp) {
  ViewerOptions o = loopback();
  o.queue_frames = 2;
  Viewer v(o);
  WsClient ws(v.port());  // never acknowledges a frame: it gets two, then nothing until it does
  ASSERT_TRUE(ws.connected()) << ws.error();
  ASSERT_TRUE(ws.wait_for([](const auto& ms) { return WsClient::count_type(ms, "hello") == 1; }));
  for (int i = 0; i < 2000; ++i) v.push(frame(i, 50));  // would hang if push waited for the browser
  for (int k = 0; k < 300 && v.stats().frames_sent < 2; ++k) std::this_thread::sleep_for(10ms);
  const ViewerStats s = v.stats();
  EXPECT_EQ(s.pushed, 2000);
  EXPECT_GT(s.dropped, 0) << "the viewer thread cannot have drawn 2000 frames";
  EXPECT_LE(s.frames_sent, 3) << "frames wait for the page's acknowledgement";
  // Acknowledging gets the newest frame.
  ws.send("ack");
  ws.send("ack");
  ASSERT_TRUE(ws.wait_for([](const auto& ms) {
    for (const auto& m : ms)
      if (!m.binary && m.as_json().value("type", "") == "frame" && m.as_json()["i"] == 1999) return true;
    return false;
  }));
}

// A page that completes the WebSocket handshake and then never reads: a browser tab frozen by its machine. Its receive
// buffer is made small, so that writes to it block once what is in flight fills the two sockets' buffers.
class StalledPage {
 public:
  explicit StalledPage(int port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd_ < 0) return;
    const int small = 4096;
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
    const timeval wait{5, 0};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &wait, sizeof wait);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    ::inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
    if (::connect(fd_, reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0) return;
    const std::string self = "127.0.0.1:" + std::to_string(port);
    const std::string request = "GET /ws HTTP/1.1\r\nHost: " + self +
                                "\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                                "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
                                "Origin: http://" + self + "\r\n\r\n";
    if (::send(fd_, request.data(), request.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(request.size())) return;
    std::string head;  // the response's header, one byte at a time: nothing of the messages after it is read
    char ch = 0;
    while (head.find("\r\n\r\n") == std::string::npos && ::recv(fd_, &ch, 1, 0) == 1) head += ch;
    upgraded_ = head.rfind("HTTP/1.1 101", 0) == 0;
  }
  ~StalledPage() {
    if (fd_ >= 0) ::close(fd_);
  }
  bool upgraded() const { return upgraded_; }
  // Sends a text message as a client must (masked, RFC 6455 5.3), of at most 125 bytes.
  bool send_text(const std::string& text) {
    const unsigned char mask[4] = {0x12, 0x34, 0x56, 0x78};
    std::string frame = {static_cast<char>(0x81), static_cast<char>(0x80 | text.size())};
    frame.append(reinterpret_cast<const char*>(mask), 4);
    for (std::size_t i = 0; i < text.size(); ++i) frame += static_cast<char>(text[i] ^ mask[i % 4]);
    return ::send(fd_, frame.data(), frame.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(frame.size());
  }

 private:
  int fd_ = -1;
  bool upgraded_ = false;
};

// 20000 poses: the hello that carries them is about 1.5 MB of JSON.
Trajectory long_ground_truth() {
  Trajectory gt;
  for (int i = 0; i < 20000; ++i) {
    StampedPose p;
    p.t = 1'000'000'000 + i * 5'000'000LL;
    p.p_WR = Eigen::Vector3d(std::sin(0.001 * i), std::cos(0.0013 * i), 0.1 * std::sin(0.0007 * i));
    gt.poses.push_back(p);
  }
  return gt;
}

bool is_hello(const WsClient::Message& m) {  // without parsing: the ground truth makes hellos of megabytes
  constexpr std::string_view tail = R"("type":"hello"})";  // (nlohmann sorts the keys: "type" comes last)
  return !m.binary && m.data.size() >= tail.size() &&
         m.data.compare(m.data.size() - tail.size(), tail.size(), tail) == 0;
}

// Each page has its own sender: a page that stops reading holds up nothing but itself. Every new ground truth goes
// to both pages in a hello of about 1.5 MB, so the stalled page's buffers are full after the first few; before the
// per-page senders, the viewer thread then waited in a write to it for CivetWeb's 10 s timeout, and the other page got
// nothing meanwhile.
TEST(Viewer, APageThatStopsReadingDelaysNoOtherPage) {
  ViewerOptions o = loopback();
  o.lower_priority = false;  // a loaded machine's other tests must not starve the pages' senders past the bound
  Viewer v(o);
  StalledPage stalled(v.port());
  ASSERT_TRUE(stalled.upgraded());
  for (int k = 0; k < 500 && v.stats().clients < 1; ++k) std::this_thread::sleep_for(10ms);
  WsClient page(v.port());
  ASSERT_TRUE(page.connected()) << page.error();
  const auto hellos = [](const auto& ms) { return std::count_if(ms.begin(), ms.end(), is_hello); };
  ASSERT_TRUE(page.wait_for([&](const auto& ms) { return hellos(ms) == 1; }));
  ASSERT_EQ(v.stats().clients, 2);
  const Trajectory gt = long_ground_truth();
  for (std::ptrdiff_t k = 2; k <= 10; ++k) {
    v.set_ground_truth(gt);
    ASSERT_TRUE(page.wait_for([&](const auto& ms) { return hellos(ms) >= k; }, 8s))
        << "hello " << k << " did not come within 8 s: the viewer waited on the stalled page (10 s)";
  }
  v.push(frame(7));
  EXPECT_TRUE(page.wait_for([](const auto& ms) {
    return std::any_of(ms.begin(), ms.end(), [](const auto& m) {
      return !m.binary && !is_hello(m) && m.as_json().value("type", "") == "frame" && m.as_json()["i"] == 7;
    });
  }, 8s)) << "no frame within 8 s";
  EXPECT_EQ(v.stats().clients, 2) << "the stalled page is still connected";
}

// A page that took nothing for write_timeout_ms has its stream cut (counted); the page's next message (it pings every
// 5 s) closes it, which frees its place: the page then reconnects and starts afresh, instead of showing a frozen run.
TEST(Viewer, APageCutOffByAFailedWriteIsClosedAtItsNextMessage) {
  ViewerOptions o = loopback();
  o.lower_priority = false;
  o.write_timeout_ms = 300;
  Viewer v(o);
  StalledPage stalled(v.port());
  ASSERT_TRUE(stalled.upgraded());
  for (int k = 0; k < 500 && v.stats().clients < 1; ++k) std::this_thread::sleep_for(10ms);
  ASSERT_EQ(v.stats().clients, 1);
  const Trajectory gt = long_ground_truth();
  for (int k = 0; k < 100 && v.stats().pages_cut == 0; ++k) {  // hellos of 1.5 MB until a write fails
    v.set_ground_truth(gt);
    std::this_thread::sleep_for(100ms);
  }
  ASSERT_EQ(v.stats().pages_cut, 1);
  EXPECT_EQ(v.stats().clients, 1) << "a page is closed only when it is heard from";
  ASSERT_TRUE(stalled.send_text("ping"));
  for (int k = 0; k < 1000 && v.stats().clients > 0; ++k) std::this_thread::sleep_for(10ms);
  EXPECT_EQ(v.stats().clients, 0) << "the cut page was not closed at its message";
  WsClient again(v.port());
  ASSERT_TRUE(again.connected()) << again.error();
  EXPECT_TRUE(again.wait_for([](const auto& ms) { return std::count_if(ms.begin(), ms.end(), is_hello) == 1; }));
  for (const int bad_ms : {99, 600001}) {
    ViewerOptions bad = loopback();
    bad.write_timeout_ms = bad_ms;
    try {
      bad.validate();
      ADD_FAILURE() << "accepted write_timeout_ms = " << bad_ms;
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("write_timeout_ms = " + std::to_string(bad_ms)), std::string::npos);
    }
  }
}

TEST(Viewer, AWebSocketFromAnotherOriginIsRefused) {
  Viewer v(loopback());
  const std::string port = std::to_string(v.port());
  // Another site; a name hidden behind user info; another local page (another port).
  for (const std::string& origin : {std::string("http://evil.example"), "http://localhost:1@evil.example:" + port,
                                   std::string("http://localhost:1")}) {
    WsClient ws(v.port(), origin.c_str());
    EXPECT_TRUE(!ws.connected() || ws.wait_for([](const auto&) { return false; }, 3s) || ws.closed()) << origin;
    EXPECT_EQ(v.stats().clients, 0) << origin;
  }
  // Through a tunnel (ssh -L 9000:127.0.0.1:PORT): Host and Origin name the tunnel's port — the page's own.
  {
    char err[256] = {};
    const std::string request =
        "GET /ws HTTP/1.1\r\nHost: localhost:9000\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
        "Origin: http://localhost:9000\r\n\r\n";
    mg_connection* c = mg_download("127.0.0.1", v.port(), 0, err, sizeof err, "%s", request.c_str());
    ASSERT_NE(c, nullptr) << err;
    EXPECT_EQ(mg_get_response_info(c)->status_code, 101);
    mg_close_connection(c);
  }
  WsClient local(v.port(), ("http://localhost:" + port).c_str());  // the page opened as localhost
  ASSERT_TRUE(local.connected()) << local.error();
  EXPECT_TRUE(local.wait_for([](const auto& ms) { return WsClient::count_type(ms, "hello") == 1; }));
}

TEST(Viewer, OnLoopbackItAnswersOnlyLoopbackNames) {
  // DNS rebinding: a page of evil.example whose name now resolves to 127.0.0.1 sends Host: evil.example.
  Viewer v(loopback());
  const std::string port = std::to_string(v.port());
  EXPECT_EQ(http_get(v.port(), "/api/status", "evil.example:" + port).status, 403);
  EXPECT_EQ(http_get(v.port(), "/", "evil.example").status, 403);
  EXPECT_EQ(http_get(v.port(), "/api/status", "localhost:" + port).status, 200);
  EXPECT_EQ(http_get(v.port(), "/api/status", "127.0.0.1:" + port).status, 200);
}

TEST(Viewer, AFifthPageIsRefused) {
  // Each WebSocket holds a server thread: a few pages at most, so that plain requests are still answered.
  Viewer v(loopback());
  std::vector<std::unique_ptr<WsClient>> pages;
  for (int i = 0; i < 4; ++i) {
    pages.push_back(std::make_unique<WsClient>(v.port()));
    ASSERT_TRUE(pages.back()->connected());
    ASSERT_TRUE(pages.back()->wait_for([](const auto& ms) { return WsClient::count_type(ms, "hello") == 1; }));
  }
  WsClient fifth(v.port());
  EXPECT_TRUE(!fifth.connected() || fifth.wait_for([](const auto&) { return false; }, 3s) || fifth.closed());
  EXPECT_EQ(v.stats().clients, 4);
  EXPECT_EQ(http_get(v.port(), "/api/status").status, 200);
}

// Pages that connect at the same moment all pass the check made before the handshake: the limit is enforced when
// a page is added. Eight at once: four are served (hello), the others closed without one.
TEST(Viewer, PagesConnectingAtOnceNeverExceedTheLimit) {
  Viewer v(loopback());
  std::vector<std::unique_ptr<WsClient>> pages(8);
  std::vector<std::thread> openers;
  for (auto& page : pages) openers.emplace_back([&] { page = std::make_unique<WsClient>(v.port()); });
  for (auto& t : openers) t.join();
  const auto hello = [](const auto& ms) { return WsClient::count_type(ms, "hello") == 1; };
  int served = 0, refused = 0;
  for (auto& page : pages) {
    if (page->connected() && page->wait_for(hello)) {  // (the wait ends at once for a page closed by the viewer)
      ++served;
    } else {
      ++refused;
      EXPECT_TRUE(!page->connected() || page->closed()) << "a page over the limit is left open";
    }
  }
  EXPECT_EQ(served, 4);
  EXPECT_EQ(refused, 4);
  EXPECT_EQ(v.stats().clients, 4);
  EXPECT_EQ(http_get(v.port(), "/api/status").status, 200);
}

TEST(Viewer, AddressesAreIpv4AndPortsAndBadOnesAreNamed) {
  EXPECT_EQ(parse_address("127.0.0.1:8080"), std::make_pair(std::string("127.0.0.1"), 8080));
  EXPECT_EQ(parse_address("9000"), std::make_pair(std::string("127.0.0.1"), 9000)) << "loopback by default";
  EXPECT_EQ(parse_address("localhost:0"), std::make_pair(std::string("127.0.0.1"), 0));
  EXPECT_EQ(parse_address("0.0.0.0:80").first, "0.0.0.0");
  for (const char* bad : {"", "host:80", "127.0.0.1:", "127.0.0.1:70000", "[::1]:80", "1.2.3:4", "127.0.0.1:x"}) {
    try {
      parse_address(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
}

TEST(Viewer, APortInUseIsAnIoErrorNamingTheAddress) {
  Viewer first(loopback());
  ViewerOptions o;
  o.address = "127.0.0.1:" + std::to_string(first.port());
  try {
    Viewer second(o);
    FAIL() << "bound a port in use";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find(o.address), std::string::npos) << e.what();
  }
}

TEST(Viewer, StopsCleanlyWithClientsConnectedAndTwice) {
  auto v = std::make_unique<Viewer>(loopback());
  WsClient a(v->port()), b(v->port());
  ASSERT_TRUE(a.connected() && b.connected());
  for (int i = 0; i < 20; ++i) v->push(frame(i));
  v->stop();
  v->stop();
  v.reset();
}

// ---- replay ---------------------------------------------------------------------------------------------------

fs::path write_run_folder() {
  const fs::path dir = fs::temp_directory_path() / "rtslam_test_viz_run";
  fs::remove_all(dir);
  fs::create_directories(dir);
  Trajectory est, gt;
  std::vector<io::FrameStats> rows;
  OverlayWriter ov((dir / "overlays").string());
  for (int i = 0; i < 20; ++i) {
    StampedPose p;
    p.t = 1'000'000'000 + i * 50'000'000LL;
    p.p_WR = Eigen::Vector3d(0.1 * i, 0.02 * i * i, 0.0);
    p.cov = Eigen::Matrix<double, 6, 6>::Identity() * 1e-4;
    est.poses.push_back(p);
    StampedPose g = p;
    g.cov.reset();
    g.p_WR += Eigen::Vector3d(0.001 * std::sin(i), 0.002 * std::cos(0.7 * i), 0.0005 * i);  // errors that vary
    g.q_WR = Eigen::Quaterniond(Eigen::AngleAxisd(0.003 * std::sin(0.5 * i), Eigen::Vector3d(0.3, 0.5, 0.8).normalized()));
    gt.poses.push_back(g);
    io::FrameStats f;
    f.t = p.t;
    f.matched = 10 + i;
    f.t_total_ms = 2.0;
    rows.push_back(f);
    FrameReport r = frame(i);
    r.t = p.t;
    ov.write(r);
  }
  ov.close();
  io::write_trajectory_csv((dir / "trajectory.csv").string(), est);
  io::write_tum((dir / "groundtruth.txt").string(), gt);
  io::FramesCsvWriter fw((dir / "frames.csv").string());
  for (const auto& f : rows) fw.write(f);
  fw.close();
  std::vector<io::MapPoint> pts(3);
  for (int i = 0; i < 3; ++i) {
    pts[static_cast<std::size_t>(i)].id = static_cast<std::uint64_t>(i);
    pts[static_cast<std::size_t>(i)].p_W = Eigen::Vector3d(i, 0, 1);
    pts[static_cast<std::size_t>(i)].cov = Eigen::Matrix3d::Identity() * 0.04;
  }
  io::write_map_ply((dir / "map.ply").string(), pts);
  io::write_summary_json((dir / "summary.json").string(),
                         {{"dataset", {{"name", "unit"}, {"kind", "test"}}}, {"seed", 4}, {"frames", 20}});
  return dir;
}

TEST(Replay, ReadsARunFolderWithItsOverlays) {
  const fs::path dir = write_run_folder();
  const RunRecording rec = load_run(dir.string());
  EXPECT_EQ(rec.title, "unit (test), seed 4");
  ASSERT_EQ(rec.history.size(), 20u);
  EXPECT_EQ(rec.history[3].stats.matched, 13) << "frames.csv joined by time";
  EXPECT_TRUE(rec.history[3].has_timing);
  EXPECT_EQ(rec.history[3].nis.count, 1) << "NIS from the overlay index";
  EXPECT_TRUE(std::isfinite(rec.history[5].nees)) << "NEES against groundtruth.txt";
  ASSERT_EQ(rec.map.size(), 3u);
  EXPECT_NEAR(rec.map[1].cov_W(0, 0), 0.04, 1e-12);
  EXPECT_FALSE(rec.map_types_known);
  // A map written with its types (as `rtslam run` writes it): the replay colours by type.
  std::vector<io::MapPoint> typed(2);
  typed[0].euclidean = false;
  typed[1].euclidean = true;
  io::write_map_ply((dir / "map.ply").string(), typed);
  const RunRecording with_types = load_run(dir.string());
  EXPECT_TRUE(with_types.map_types_known);
  ASSERT_EQ(with_types.map.size(), 2u);
  EXPECT_FALSE(with_types.map[0].euclidean);
  EXPECT_TRUE(with_types.map[1].euclidean);
  ASSERT_EQ(rec.overlays.size(), 20u);
  EXPECT_EQ(rec.camera.width, 160);
}

TEST(Replay, ThePoseNeesIsEvalsDefinition) {
  const fs::path dir = write_run_folder();
  const RunRecording rec = load_run(dir.string());
  const auto [est, gt] = eval::associate(io::read_trajectory((dir / "trajectory.csv").string()),
                                         io::read_trajectory((dir / "groundtruth.txt").string()));
  const eval::NeesSeries ref = eval::compute_nees(est, gt);
  ASSERT_EQ(ref.nees.size(), rec.history.size());
  for (std::size_t i = 0; i < ref.nees.size(); ++i) {
    EXPECT_NEAR(rec.history[i].nees, ref.nees[i], 1e-9 * (1.0 + ref.nees[i])) << "pose " << i;
  }
  EXPECT_GT(ref.nees.back(), 0.1) << "a non-trivial check";
}

TEST(Replay, AFolderWithoutATrajectoryIsNamed) {
  const fs::path dir = fs::temp_directory_path() / "rtslam_test_viz_empty";
  fs::remove_all(dir);
  fs::create_directories(dir);
  try {
    load_run(dir.string());
    FAIL();
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("trajectory.csv"), std::string::npos) << e.what();
  }
}

TEST(Replay, TheViewerServesTheRecordingAndItsOverlays) {
  const fs::path dir = write_run_folder();
  Viewer v(loopback());
  v.show_recording(load_run(dir.string()));
  WsClient ws(v.port());
  ASSERT_TRUE(ws.connected()) << ws.error();
  ASSERT_TRUE(ws.wait_for([](const auto& ms) { return WsClient::count_type(ms, "status") == 1; }));
  const auto ms = ws.messages();
  const json hello = ms.front().as_json();
  EXPECT_EQ(hello["mode"], "replay");
  EXPECT_EQ(hello["overlays"].size(), 20u);
  EXPECT_EQ(WsClient::count_type(ms, "align"), 1u) << "the ground truth's alignment";
  std::size_t landmarks = 0, entries = 0;
  for (const auto& m : ms) {
    const json j = m.as_json();
    if (j["type"] == "frame") landmarks = j["landmarks"].size();
    if (j["type"] == "history") entries += j["entries"].size();
  }
  EXPECT_EQ(landmarks, 3u);
  EXPECT_EQ(entries, 20u);
  const HttpResponse png = http_get(v.port(), "/api/overlay/4");
  EXPECT_EQ(png.status, 200);
  EXPECT_EQ(png.content_type, "image/png");
  EXPECT_EQ(png.body.substr(1, 3), "PNG");
  EXPECT_EQ(http_get(v.port(), "/api/overlay/99").status, 404);
}

TEST(Replay, AnOverlayIndexNamingAFileOutsideItsFolderIsRefused) {
  // A run folder from elsewhere whose overlays/index.csv names /etc/passwd, ../secret or a symbolic link: the
  // viewer served those files as image/png.
  const fs::path dir = write_run_folder();
  const fs::path index = dir / "overlays" / "index.csv";
  std::string original;
  {
    std::ifstream in(index);
    original.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const auto second_line = original.find('\n') + 1;
  const auto file_start = original.find(',', original.find(',', second_line) + 1) + 1;
  const auto file_end = original.find(',', file_start);
  const std::string first_file = original.substr(file_start, file_end - file_start);
  for (const std::string& bad : std::vector<std::string>{"/etc/passwd", "../secret.png", "sub/dir.png"}) {
    std::string text = original;
    text.replace(file_start, file_end - file_start, bad);
    std::ofstream(index) << text;
    try {
      load_run(dir.string());
      ADD_FAILURE() << bad << " accepted";
    } catch (const IoError& e) {
      EXPECT_NE(std::string(e.what()).find("index.csv:2: '" + bad + "' is not a file name in the overlays folder"),
                std::string::npos)
          << e.what();
    }
  }
  // A symbolic link in the folder (to a file outside it) is not served.
  std::ofstream(index) << original;
  std::ofstream(dir / "secret.txt") << "TOP-SECRET";
  fs::remove(dir / "overlays" / first_file);
  fs::create_symlink(dir / "secret.txt", dir / "overlays" / first_file);
  Viewer v(loopback());
  v.show_recording(load_run(dir.string()));
  const HttpResponse r = http_get(v.port(), "/api/overlay/0");
  EXPECT_EQ(r.status, 404);
  EXPECT_EQ(r.body.find("TOP-SECRET"), std::string::npos);
  EXPECT_EQ(http_get(v.port(), "/api/overlay/1").status, 200);
}

}  // namespace
