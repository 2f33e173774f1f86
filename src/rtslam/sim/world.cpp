#include "rtslam/sim/world.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>  // cv::IMREAD_*
#include <opencv2/imgproc.hpp>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/io/codecs.hpp"

namespace rtslam::sim {

using Eigen::Vector2d;
using Eigen::Vector3d;
using Eigen::Vector3f;

namespace {

std::vector<BoxSpec> read_boxes(YamlMap& parent, const std::string& key, bool pillars) {
  std::vector<BoxSpec> out;
  if (!parent.has(key)) return out;
  YAML::Node list;
  parent.get(key, list);
  if (!list.IsSequence()) throw ConfigError(fmt::format("{}: '{}' must be a list", parent.where(), parent.path_of(key)));
  for (std::size_t i = 0; i < list.size(); ++i) {
    YamlMap m(list[i], fmt::format("{}[{}]", parent.path_of(key), i));
    BoxSpec b;
    Eigen::Vector2d c;
    m.get_matrix("center", c);
    b.center = c;
    if (pillars) {
      Eigen::Vector2d s(0.4, 0.4);
      m.get_matrix("size", s);
      b.size = Vector3d(s.x(), s.y(), 0.0);
    } else {
      m.get_matrix("size", b.size);
    }
    m.finish();
    out.push_back(b);
  }
  return out;
}

}  // namespace

WorldConfig WorldConfig::from_yaml(YamlMap& map) {
  WorldConfig c;
  map.get("seed", c.seed);
  if (map.has("room")) {
    YamlMap room = map.child("room");
    room.get_matrix("size", c.room_size);
    room.get_matrix("center", c.room_center);
    room.get("floor", c.floor_z);
    room.finish();
  }
  map.get("texel_size", c.texel_size);
  map.get("texture", c.texture);
  map.get("uniform_grey", c.uniform_grey);
  map.get("images", c.images);
  map.get("image_tile_size", c.image_tile_size);
  c.boxes = read_boxes(map, "boxes", false);
  c.pillars = read_boxes(map, "pillars", true);
  map.get("random_boxes", c.random_boxes);
  map.finish();
  c.validate(map.where());
  return c;
}

WorldConfig WorldConfig::from_file(const std::string& path) {
  YamlMap map(load_yaml_file(path), path);
  if (map.has("world")) {  // a preset file may nest the world under `world:`
    YamlMap w = map.child("world");
    WorldConfig c = from_yaml(w);
    map.finish();
    return c;
  }
  return from_yaml(map);
}

std::vector<std::string> WorldConfig::preset_names() { return {"room", "small-room", "hall"}; }

WorldConfig WorldConfig::preset(const std::string& name) {
  WorldConfig c;
  if (name == "room") {
    c.room_size = Vector3d(8.0, 6.0, 3.0);
    c.boxes = {{Vector2d(2.6, 1.7), Vector3d(0.8, 0.6, 0.9)},
               {Vector2d(-2.8, -1.8), Vector3d(1.0, 0.7, 0.6)},
               {Vector2d(-2.9, 1.9), Vector3d(0.5, 0.5, 1.4)},
               {Vector2d(3.0, -2.0), Vector3d(0.6, 0.9, 0.5)}};
    c.pillars = {{Vector2d(1.8, -1.2), Vector3d(0.35, 0.35, 0.0)}, {Vector2d(-1.9, 0.9), Vector3d(0.3, 0.3, 0.0)}};
  } else if (name == "small-room") {
    c.room_size = Vector3d(5.0, 4.0, 2.6);
    c.boxes = {{Vector2d(1.7, 1.2), Vector3d(0.6, 0.5, 0.8)}, {Vector2d(-1.8, -1.3), Vector3d(0.7, 0.6, 0.5)}};
    c.pillars = {{Vector2d(-1.4, 1.2), Vector3d(0.25, 0.25, 0.0)}};
  } else if (name == "hall") {
    c.room_size = Vector3d(16.0, 12.0, 5.0);
    c.texel_size = 0.008;
    c.pillars = {{Vector2d(-4.0, -3.0), Vector3d(0.5, 0.5, 0.0)}, {Vector2d(4.0, -3.0), Vector3d(0.5, 0.5, 0.0)},
                 {Vector2d(-4.0, 3.0), Vector3d(0.5, 0.5, 0.0)}, {Vector2d(4.0, 3.0), Vector3d(0.5, 0.5, 0.0)}};
    c.random_boxes = 8;
  } else {
    throw ConfigError(fmt::format("world preset '{}' is unknown (known: room, small-room, hall)", name));
  }
  return c;
}

void WorldConfig::validate(const std::string& where) const {
  for (int i = 0; i < 3; ++i)
    require_bound(room_size[i] >= 1.0 && room_size[i] <= 200.0, where, "room.size", room_size[i], "in [1, 200] m");
  require_bound(texel_size >= 0.0005 && texel_size <= 0.1, where, "texel_size", texel_size, "in [0.0005, 0.1] m");
  const double texels = 2.0 * (room_size.x() * room_size.y() + room_size.x() * room_size.z() +
                               room_size.y() * room_size.z()) / (texel_size * texel_size);
  require_bound(texels <= 4e8, where, "texel_size", texel_size, "large enough for at most 4e8 room texels");
  if (texture != "procedural" && texture != "uniform" && texture != "images")
    throw ConfigError(fmt::format("{}: texture = '{}' must be procedural, uniform or images", where, texture));
  require_bound(uniform_grey >= 0 && uniform_grey <= 255, where, "uniform_grey", uniform_grey, "in [0, 255]");
  if (texture == "images" && images.empty())
    throw ConfigError(fmt::format("{}: texture = images needs a non-empty 'images' list", where));
  require_bound(image_tile_size > 0.0, where, "image_tile_size", image_tile_size, "> 0 m");
  require_bound(random_boxes >= 0 && random_boxes <= 100, where, "random_boxes", random_boxes, "in [0, 100]");
  auto check = [&](const std::vector<BoxSpec>& list, const char* key, bool pillar) {
    for (const BoxSpec& b : list) {
      for (int i = 0; i < (pillar ? 2 : 3); ++i)
        require_bound(b.size[i] > 0.01, where, std::string(key) + ".size", b.size[i], "> 0.01 m");
      for (int i = 0; i < 2; ++i)
        require_bound(std::abs(b.center[i]) + 0.5 * b.size[i] < 0.5 * room_size[i], where,
                      std::string(key) + ".center", b.center[i], "such that the box lies inside the room");
      if (!pillar)
        require_bound(b.size.z() < room_size.z(), where, std::string(key) + ".size", b.size.z(),
                      "below the ceiling");
    }
  };
  check(boxes, "boxes", false);
  check(pillars, "pillars", true);
}

int WorldConfig::fit_to_points(const std::vector<Vector3d>& points, double margin, double clearance) {
  if (points.empty()) return 0;
  Vector3d lo = points.front(), hi = points.front();
  for (const Vector3d& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Vector3d cur_lo(room_center.x() - 0.5 * room_size.x(), room_center.y() - 0.5 * room_size.y(), floor_z);
  const Vector3d cur_hi = cur_lo + room_size;
  const bool inside = ((lo.array() - margin) >= cur_lo.array()).all() && ((hi.array() + margin) <= cur_hi.array()).all();
  if (!inside) {
    for (int i = 0; i < 2; ++i) room_size[i] = std::max(room_size[i], hi[i] - lo[i] + 2.0 * margin);
    room_center = 0.5 * (lo + hi).head<2>();
    // The floor goes below the lowest point; the ceiling above the highest, at least the configured height.
    floor_z = std::min(floor_z, lo.z() - margin);
    room_size.z() = std::max(room_size.z(), hi.z() + margin - floor_z);
  }
  auto collides = [&](const BoxSpec& b, double height) {
    for (const Vector3d& p : points) {
      const Vector2d d = (p.head<2>() - room_center - b.center).cwiseAbs();
      if (d.x() < 0.5 * b.size.x() + clearance && d.y() < 0.5 * b.size.y() + clearance &&
          p.z() < floor_z + height + clearance)
        return true;
    }
    return false;
  };
  const std::size_t before = boxes.size() + pillars.size();
  std::erase_if(boxes, [&](const BoxSpec& b) { return collides(b, b.size.z()); });
  std::erase_if(pillars, [&](const BoxSpec& b) { return collides(b, room_size.z()); });
  if (random_boxes > 0) random_boxes = 0;  // their layout is unknown here: drop them rather than risk a collision
  return static_cast<int>(before - boxes.size() - pillars.size());
}

float FaceTexture::sample(float s, float t) const {
  // Clamped so that NaN gives 0 (std::clamp would pass it on, and the texel index with it); otherwise as clamp.
  s = std::min(std::max(0.0f, s), static_cast<float>(width - 1));
  t = std::min(std::max(0.0f, t), static_cast<float>(height - 1));
  const int x0 = std::min(static_cast<int>(s), width - 2 < 0 ? 0 : width - 2);
  const int y0 = std::min(static_cast<int>(t), height - 2 < 0 ? 0 : height - 2);
  const int x1 = std::min(x0 + 1, width - 1), y1 = std::min(y0 + 1, height - 1);
  const float fx = s - static_cast<float>(x0), fy = t - static_cast<float>(y0);
  const std::uint8_t* r0 = texels.data() + static_cast<std::size_t>(y0) * static_cast<std::size_t>(width);
  const std::uint8_t* r1 = texels.data() + static_cast<std::size_t>(y1) * static_cast<std::size_t>(width);
  const float top = static_cast<float>(r0[x0]) + fx * (static_cast<float>(r0[x1]) - static_cast<float>(r0[x0]));
  const float bot = static_cast<float>(r1[x0]) + fx * (static_cast<float>(r1[x1]) - static_cast<float>(r1[x0]));
  return top + fy * (bot - top);
}

World::World(const WorldConfig& config) : config_(config) {
  config_.validate("world");
  inv_texel_ = static_cast<float>(1.0 / config_.texel_size);
  const Vector3d c0(config_.room_center.x(), config_.room_center.y(), config_.floor_z);
  const Vector3d half(0.5 * config_.room_size.x(), 0.5 * config_.room_size.y(), 0.0);
  room_min_ = (c0 - half).cast<float>();
  room_max_ = (c0 + half + Vector3d(0, 0, config_.room_size.z())).cast<float>();
  add_faces(room_min_, room_max_);  // faces 0..5: the room, seen from inside

  std::vector<BoxSpec> all = config_.boxes;
  for (BoxSpec p : config_.pillars) {
    p.size.z() = config_.room_size.z();
    all.push_back(p);
  }
  // Random boxes: seeded, away from the room centre (where the presets' trajectories move), not overlapping.
  Rng rng(config_.seed * 0x9E3779B97F4A7C15ULL + 17);
  for (int k = 0, tries = 0; k < config_.random_boxes && tries < 1000; ++tries) {
    BoxSpec b;
    b.size = Vector3d(randu(rng, 0.3, 1.2), randu(rng, 0.3, 1.2), randu(rng, 0.3, 0.7 * config_.room_size.z()));
    const Vector2d lim(0.5 * config_.room_size.x() - 0.5 * b.size.x() - 0.05,
                       0.5 * config_.room_size.y() - 0.5 * b.size.y() - 0.05);
    b.center = Vector2d(randu(rng, -lim.x(), lim.x()), randu(rng, -lim.y(), lim.y()));
    if (std::abs(b.center.x()) < 0.3 * config_.room_size.x() && std::abs(b.center.y()) < 0.3 * config_.room_size.y())
      continue;
    bool overlap = false;
    for (const BoxSpec& o : all)
      overlap |= std::abs(o.center.x() - b.center.x()) < 0.5 * (o.size.x() + b.size.x()) + 0.1 &&
                 std::abs(o.center.y() - b.center.y()) < 0.5 * (o.size.y() + b.size.y()) + 0.1;
    if (overlap) continue;
    all.push_back(b);
    ++k;
  }
  for (const BoxSpec& b : all) {
    const Vector2d c = b.center + config_.room_center;
    const Vector3f lo(static_cast<float>(c.x() - 0.5 * b.size.x()), static_cast<float>(c.y() - 0.5 * b.size.y()),
                      room_min_.z());
    const Vector3f hi(static_cast<float>(c.x() + 0.5 * b.size.x()), static_cast<float>(c.y() + 0.5 * b.size.y()),
                      std::min(room_max_.z(), room_min_.z() + static_cast<float>(b.size.z())));
    all_boxes_.push_back(static_cast<int>(boxes_.size()));
    boxes_.push_back(Aabb{lo, hi, static_cast<int>(faces_.size())});
    add_faces(lo, hi);
  }
  generate_textures();
}

void World::add_faces(const Vector3f& lo, const Vector3f& hi) {
  for (int axis = 0; axis < 3; ++axis) {
    const int b = (axis + 1) % 3, c = (axis + 2) % 3;
    for (int side = 0; side < 2; ++side) {
      Face f;
      f.axis = axis;
      f.coord = side == 0 ? lo[axis] : hi[axis];
      f.lo = Eigen::Vector2f(lo[b], lo[c]);
      f.hi = Eigen::Vector2f(hi[b], hi[c]);
      f.texture = static_cast<int>(faces_.size());
      faces_.push_back(f);
    }
  }
}

bool World::is_free(const Vector3d& p, double clearance) const {
  const Vector3f q = p.cast<float>();
  const auto cl = static_cast<float>(clearance);
  for (int i = 0; i < 3; ++i)
    if (q[i] < room_min_[i] + cl || q[i] > room_max_[i] - cl) return false;
  for (const Aabb& b : boxes_) {
    bool inside = true;
    for (int i = 0; i < 3; ++i) inside &= q[i] > b.lo[i] - cl && q[i] < b.hi[i] + cl;
    if (inside) return false;
  }
  return true;
}

[[gnu::always_inline]] inline bool World::cast_ray(const Vector3f& o, const Vector3f& d, std::span<const int> boxes,
                                                   Hit& hit) const {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  float inv[3];
  for (int i = 0; i < 3; ++i) inv[i] = d[i] != 0.0f ? 1.0f / d[i] : kInf;
  // Room: exit distance through the slab of each axis.
  float best = kInf;
  int face = -1;
  for (int i = 0; i < 3; ++i) {
    if (d[i] == 0.0f) continue;
    const bool pos = d[i] > 0.0f;
    const float t = ((pos ? room_max_[i] : room_min_[i]) - o[i]) * inv[i];
    if (t < best) {
      best = t;
      face = 2 * i + (pos ? 1 : 0);
    }
  }
  if (face < 0 || !(best > 0.0f)) return false;
  if (d.x() == 0.0f || d.y() == 0.0f || d.z() == 0.0f) {
    cast_boxes_parallel(o, d, boxes, best, face);
  } else {
    // Boxes: entry distance (slab test); the entry face is on the axis of the largest near distance. The near
    // plane of each slab is the lo plane for a positive direction component, else the hi plane (the same values
    // as computing both distances and swapping them).
    const bool neg[3] = {d.x() < 0.0f, d.y() < 0.0f, d.z() < 0.0f};
    for (const int k : boxes) {
      const Aabb& b = boxes_[static_cast<std::size_t>(k)];
      float t_near = ((neg[0] ? b.hi.x() : b.lo.x()) - o.x()) * inv[0];
      float t_far = ((neg[0] ? b.lo.x() : b.hi.x()) - o.x()) * inv[0];
      int axis = 0;
      for (int i = 1; i < 3; ++i) {
        const float t0 = ((neg[i] ? b.hi[i] : b.lo[i]) - o[i]) * inv[i];
        const float t1 = ((neg[i] ? b.lo[i] : b.hi[i]) - o[i]) * inv[i];
        axis = t0 > t_near ? i : axis;
        t_near = t0 > t_near ? t0 : t_near;
        t_far = std::min(t_far, t1);
      }
      if (t_near <= t_far && t_near > 0.0f && t_near < best) {
        best = t_near;
        face = b.first_face + 2 * axis + (neg[axis] ? 1 : 0);
      }
    }
  }
  hit.t = best;
  hit.face = face;
  return true;
}

void World::cast_boxes_parallel(const Vector3f& o, const Vector3f& d, std::span<const int> boxes, float& best,
                                int& face) const {
  // A direction with a zero component (rare: test rays, axis-aligned cameras): the general slab test.
  constexpr float kInf = std::numeric_limits<float>::infinity();
  Vector3f inv;
  for (int i = 0; i < 3; ++i) inv[i] = d[i] != 0.0f ? 1.0f / d[i] : kInf;
  for (const int k : boxes) {
    const Aabb& b = boxes_[static_cast<std::size_t>(k)];
    float t_near = -kInf, t_far = kInf;
    int axis = -1;
    for (int i = 0; i < 3; ++i) {
      float t0 = (b.lo[i] - o[i]) * inv[i], t1 = (b.hi[i] - o[i]) * inv[i];
      if (d[i] == 0.0f) {
        if (o[i] <= b.lo[i] || o[i] >= b.hi[i]) t_far = -kInf;  // parallel and outside the slab: no hit
        continue;
      }
      if (t0 > t1) std::swap(t0, t1);
      if (t0 > t_near) {
        t_near = t0;
        axis = i;
      }
      t_far = std::min(t_far, t1);
    }
    if (axis >= 0 && t_near <= t_far && t_near > 0.0f && t_near < best) {
      best = t_near;
      face = b.first_face + 2 * axis + (d[axis] > 0.0f ? 0 : 1);
    }
  }
}

[[gnu::always_inline]] inline float World::shade_hit(int face_index, const Vector3f& p) const {
  if (!markers_.empty()) {
    const Vector3d pd = p.cast<double>();
    for (const Marker& m : markers_)
      if ((pd - m.center).squaredNorm() <= m.radius * m.radius) return m.grey;
  }
  // FaceTexture::sample with the face's constants precomputed (same arithmetic, same result).
  const FaceSampler& f = samplers_[static_cast<std::size_t>(face_index)];
  // p's coordinates on the texture axes by constant index: p[f.b] sent p through memory.
  const float pb = f.b == 0 ? p.x() : f.b == 1 ? p.y() : p.z();
  const float pc = f.c == 0 ? p.x() : f.c == 1 ? p.y() : p.z();
  const float s = std::min(std::max(0.0f, (pb - f.lo_b) * inv_texel_), f.s_max);  // NaN -> 0, as sample()
  const float t = std::min(std::max(0.0f, (pc - f.lo_c) * inv_texel_), f.t_max);
  const int x0 = std::min(static_cast<int>(s), f.x0_max), y0 = std::min(static_cast<int>(t), f.y0_max);
  const float fx = s - static_cast<float>(x0), fy = t - static_cast<float>(y0);
  const std::uint8_t* r0 = f.texels + static_cast<std::size_t>(y0) * f.width + static_cast<std::size_t>(x0);
  const std::uint8_t* r1 = r0 + f.width;
  const float top = static_cast<float>(r0[0]) + fx * (static_cast<float>(r0[1]) - static_cast<float>(r0[0]));
  const float bot = static_cast<float>(r1[0]) + fx * (static_cast<float>(r1[1]) - static_cast<float>(r1[0]));
  return top + fy * (bot - top);
}

bool World::cast(const Vector3f& o, const Vector3f& d, Hit& hit) const { return cast_ray(o, d, all_boxes_, hit); }

bool World::cast(const Vector3f& o, const Vector3f& d, std::span<const int> boxes, Hit& hit) const {
  return cast_ray(o, d, boxes, hit);
}

float World::shade(int face, const Vector3f& p) const { return shade_hit(face, p); }

[[gnu::always_inline]] inline float World::trace_ray(const Vector3f& o, const Vector3f& d,
                                                     std::span<const int> boxes) const {
  Hit hit;
  return cast_ray(o, d, boxes, hit) ? shade_hit(hit.face, o + hit.t * d) : 0.0f;
}

bool World::vectorized() const {
#if defined(__x86_64__)
  if (!vectorized_) return false;
  // __builtin_cpu_supports also checks that the OS saves the AVX registers.
  static const bool avx2 = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return avx2;
#else
  return false;
#endif
}

void World::trace(const Rays& rays, std::span<const int> boxes, float* grey) const {
  std::size_t k = 0;
  if (markers_.empty() && vectorized()) k = trace_avx2(rays, boxes, grey);
  for (; k < rays.size; ++k)
    grey[k] = trace_ray(Vector3f(rays.o[0][k], rays.o[1][k], rays.o[2][k]),
                        Vector3f(rays.d[0][k], rays.d[1][k], rays.d[2][k]), boxes);
}

#if defined(__x86_64__)
// Eight rays per step, lane k doing exactly what cast_ray does for one ray: the same float operations in the same
// order (no FMA: the target is AVX2 alone, and the module is compiled with -ffp-contract=off, so that neither path
// fuses a multiply and an add whatever -march a build adds), the selections as blends, the comparisons as ordered
// predicates (false with NaN, as in C++), std::min(a, b) as _mm256_min_ps(b, a) (both give a when the comparison
// fails). A packet with a zero direction component goes through the plain path ray by ray (the slab test of
// parallel rays). Shading: a packet whose eight rays hit one face in vector, others lane by lane (shade_hit).
__attribute__((target("avx2"))) std::size_t World::trace_avx2(const Rays& rays, std::span<const int> boxes,
                                                              float* grey) const {
  const std::size_t n = rays.size / 8 * 8;
  const __m256 zero = _mm256_setzero_ps(), inf = _mm256_set1_ps(std::numeric_limits<float>::infinity());
  const __m256i one = _mm256_set1_epi32(1);
  for (std::size_t j = 0; j < n; j += 8) {
    __m256 ov[3], dv[3], inv[3], neg[3];
    int any_zero = 0;
    for (int i = 0; i < 3; ++i) {
      ov[i] = _mm256_loadu_ps(rays.o[i] + j);
      dv[i] = _mm256_loadu_ps(rays.d[i] + j);
      any_zero |= _mm256_movemask_ps(_mm256_cmp_ps(dv[i], zero, _CMP_EQ_OQ));
      inv[i] = _mm256_div_ps(_mm256_set1_ps(1.0f), dv[i]);
      neg[i] = _mm256_cmp_ps(dv[i], zero, _CMP_LT_OQ);
    }
    if (any_zero != 0) {
      for (std::size_t k = j; k < j + 8; ++k)
        grey[k] = trace_ray(Vector3f(rays.o[0][k], rays.o[1][k], rays.o[2][k]),
                            Vector3f(rays.d[0][k], rays.d[1][k], rays.d[2][k]), boxes);
      continue;
    }
    // Room: exit distance through the slab of each axis.
    __m256 best = inf;
    __m256i face = _mm256_set1_epi32(-1);
    for (int i = 0; i < 3; ++i) {
      const __m256 pos = _mm256_cmp_ps(dv[i], zero, _CMP_GT_OQ);
      const __m256 plane = _mm256_blendv_ps(_mm256_set1_ps(room_min_[i]), _mm256_set1_ps(room_max_[i]), pos);
      const __m256 t = _mm256_mul_ps(_mm256_sub_ps(plane, ov[i]), inv[i]);
      const __m256 closer = _mm256_cmp_ps(t, best, _CMP_LT_OQ);
      best = _mm256_blendv_ps(best, t, closer);
      const __m256i f = _mm256_add_epi32(_mm256_set1_epi32(2 * i), _mm256_and_si256(_mm256_castps_si256(pos), one));
      face = _mm256_blendv_epi8(face, f, _mm256_castps_si256(closer));
    }
    const __m256 valid = _mm256_and_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(face, _mm256_set1_epi32(-1))),
                                       _mm256_cmp_ps(best, zero, _CMP_GT_OQ));
    if (_mm256_movemask_ps(valid) == 0) {
      _mm256_storeu_ps(grey + j, zero);
      continue;
    }
    // Boxes: the slab test, entry face on the axis of the largest near distance.
    for (const int k : boxes) {
      const Aabb& b = boxes_[static_cast<std::size_t>(k)];
      __m256 t_near = _mm256_mul_ps(
          _mm256_sub_ps(_mm256_blendv_ps(_mm256_set1_ps(b.lo.x()), _mm256_set1_ps(b.hi.x()), neg[0]), ov[0]), inv[0]);
      __m256 t_far = _mm256_mul_ps(
          _mm256_sub_ps(_mm256_blendv_ps(_mm256_set1_ps(b.hi.x()), _mm256_set1_ps(b.lo.x()), neg[0]), ov[0]), inv[0]);
      __m256i axis = _mm256_setzero_si256();
      __m256 neg_axis = neg[0];
      for (int i = 1; i < 3; ++i) {
        const __m256 lo = _mm256_set1_ps(b.lo[i]), hi = _mm256_set1_ps(b.hi[i]);
        const __m256 t0 = _mm256_mul_ps(_mm256_sub_ps(_mm256_blendv_ps(lo, hi, neg[i]), ov[i]), inv[i]);
        const __m256 t1 = _mm256_mul_ps(_mm256_sub_ps(_mm256_blendv_ps(hi, lo, neg[i]), ov[i]), inv[i]);
        const __m256 later = _mm256_cmp_ps(t0, t_near, _CMP_GT_OQ);
        axis = _mm256_blendv_epi8(axis, _mm256_set1_epi32(i), _mm256_castps_si256(later));
        neg_axis = _mm256_blendv_ps(neg_axis, neg[i], later);
        t_near = _mm256_blendv_ps(t_near, t0, later);
        t_far = _mm256_min_ps(t1, t_far);
      }
      const __m256 hit = _mm256_and_ps(
          _mm256_and_ps(_mm256_cmp_ps(t_near, t_far, _CMP_LE_OQ), _mm256_cmp_ps(t_near, zero, _CMP_GT_OQ)),
          _mm256_cmp_ps(t_near, best, _CMP_LT_OQ));
      if (_mm256_movemask_ps(hit) == 0) continue;
      best = _mm256_blendv_ps(best, t_near, hit);
      const __m256i f =
          _mm256_add_epi32(_mm256_add_epi32(_mm256_set1_epi32(b.first_face), _mm256_add_epi32(axis, axis)),
                           _mm256_and_si256(_mm256_castps_si256(neg_axis), one));
      face = _mm256_blendv_epi8(face, f, _mm256_castps_si256(hit));
    }
    // Shading at the hit point o + t d.
    __m256 p[3];
    for (int i = 0; i < 3; ++i) p[i] = _mm256_add_ps(ov[i], _mm256_mul_ps(best, dv[i]));
    const int face0 = _mm256_cvtsi256_si32(face);
    if (_mm256_movemask_ps(valid) == 0xFF &&
        _mm256_movemask_epi8(_mm256_cmpeq_epi32(face, _mm256_set1_epi32(face0))) == -1) {
      // The eight rays on one face (most packets): shade_hit's arithmetic in vector, the face's constants broadcast;
      // std::max(0, v) as _mm256_max_ps(v, 0) and std::min(v, m) as _mm256_min_ps(m, v) (the same operand when
      // the comparison fails, NaN included). Only the texels are read lane by lane (no gathers).
      const FaceSampler& f = samplers_[static_cast<std::size_t>(face0)];
      const __m256 inv_texel = _mm256_set1_ps(inv_texel_);
      const __m256 s =
          _mm256_min_ps(_mm256_set1_ps(f.s_max),
                        _mm256_max_ps(_mm256_mul_ps(_mm256_sub_ps(p[f.b], _mm256_set1_ps(f.lo_b)), inv_texel), zero));
      const __m256 t =
          _mm256_min_ps(_mm256_set1_ps(f.t_max),
                        _mm256_max_ps(_mm256_mul_ps(_mm256_sub_ps(p[f.c], _mm256_set1_ps(f.lo_c)), inv_texel), zero));
      const __m256i x0 = _mm256_min_epi32(_mm256_cvttps_epi32(s), _mm256_set1_epi32(f.x0_max));
      const __m256i y0 = _mm256_min_epi32(_mm256_cvttps_epi32(t), _mm256_set1_epi32(f.y0_max));
      const __m256 fx = _mm256_sub_ps(s, _mm256_cvtepi32_ps(x0));
      const __m256 fy = _mm256_sub_ps(t, _mm256_cvtepi32_ps(y0));
      // The texel offsets y0 width + x0 in vector (a face has far fewer than 2^31 texels), then each lane's two
      // texel pairs (r0[0], r0[1]) and (r1[0], r1[1]) read as 16-bit words: the low byte is the first texel.
      alignas(32) int offset[8];
      _mm256_store_si256(reinterpret_cast<__m256i*>(offset),
                         _mm256_add_epi32(_mm256_mullo_epi32(y0, _mm256_set1_epi32(static_cast<int>(f.width))), x0));
      alignas(16) std::uint16_t top_pair[8], bottom_pair[8];
      for (int l = 0; l < 8; ++l) {
        const std::uint8_t* r0 = f.texels + static_cast<std::size_t>(offset[l]);  // as shade_hit
        std::memcpy(&top_pair[l], r0, 2);
        std::memcpy(&bottom_pair[l], r0 + f.width, 2);
      }
      const __m256i low_byte = _mm256_set1_epi32(0xFF);
      const __m256i tops = _mm256_cvtepu16_epi32(_mm_load_si128(reinterpret_cast<const __m128i*>(top_pair)));
      const __m256i bottoms = _mm256_cvtepu16_epi32(_mm_load_si128(reinterpret_cast<const __m128i*>(bottom_pair)));
      const __m256 a00 = _mm256_cvtepi32_ps(_mm256_and_si256(tops, low_byte));
      const __m256 a01 = _mm256_cvtepi32_ps(_mm256_srli_epi32(tops, 8));
      const __m256 a10 = _mm256_cvtepi32_ps(_mm256_and_si256(bottoms, low_byte));
      const __m256 a11 = _mm256_cvtepi32_ps(_mm256_srli_epi32(bottoms, 8));
      const __m256 top = _mm256_add_ps(a00, _mm256_mul_ps(fx, _mm256_sub_ps(a01, a00)));
      const __m256 bot = _mm256_add_ps(a10, _mm256_mul_ps(fx, _mm256_sub_ps(a11, a10)));
      _mm256_storeu_ps(grey + j, _mm256_add_ps(top, _mm256_mul_ps(fy, _mm256_sub_ps(bot, top))));
      continue;
    }
    // Rays on several faces, or some seeing nothing: lane by lane (gathers are slow on CPUs with the
    // gather-data-sampling fix).
    alignas(32) int faces[8], lit[8];
    alignas(32) float q[3][8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(faces), face);
    _mm256_store_si256(reinterpret_cast<__m256i*>(lit), _mm256_castps_si256(valid));
    for (int i = 0; i < 3; ++i) _mm256_store_ps(q[i], p[i]);
    for (int l = 0; l < 8; ++l)
      grey[j + l] = lit[l] != 0 ? shade_hit(faces[l], Vector3f(q[0][l], q[1][l], q[2][l])) : 0.0f;
  }
  return n;
}
#else
std::size_t World::trace_avx2(const Rays&, std::span<const int>, float*) const { return 0; }
#endif

namespace {

// A procedural, multi-scale texture of w x h texels (texel size tau metres), like a wall covered in posters,
// objects and dirt: smooth blotches, poster-sized rectangles, centimetre objects, small blobs and grain.
cv::Mat procedural_texture(int w, int h, double tau, Rng& rng) {
  const double area = w * tau * h * tau;
  auto px = [tau](double m) { return static_cast<int>(std::lround(m / tau)); };
  auto grey = [&rng] { return cv::Scalar(static_cast<int>(randu(rng, 0.0, 256.0))); };
  // Smooth low-frequency blotches (cells of ~0.3 m).
  const int gw = std::max(2, static_cast<int>(w * tau / 0.3) + 2), gh = std::max(2, static_cast<int>(h * tau / 0.3) + 2);
  cv::Mat coarse(gh, gw, CV_8UC1);
  for (int y = 0; y < gh; ++y)
    for (int x = 0; x < gw; ++x) coarse.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(randu(rng, 70.0, 190.0));
  cv::Mat tex;
  cv::resize(coarse, tex, cv::Size(w, h), 0, 0, cv::INTER_CUBIC);
  auto random_point = [&] { return cv::Point(static_cast<int>(randu(rng, 0, w)), static_cast<int>(randu(rng, 0, h))); };
  // Posters: 0.2–1.0 m rectangles, some with a frame.
  const int n_posters = static_cast<int>(area / 2.0) + 1;
  for (int i = 0; i < n_posters; ++i) {
    const cv::Point p = random_point();
    const cv::Point q = p + cv::Point(px(randu(rng, 0.2, 1.0)), px(randu(rng, 0.2, 1.0)));
    cv::rectangle(tex, p, q, grey(), cv::FILLED);
    if (randu(rng, 0, 1) < 0.5) cv::rectangle(tex, p, q, grey(), std::max(1, px(0.01)));
  }
  // Objects of 2–15 cm: rectangles, rotated rectangles, discs, ellipses, triangles.
  const int n_objects = static_cast<int>(area * 60.0);
  for (int i = 0; i < n_objects; ++i) {
    const cv::Point c = random_point();
    const double size = std::exp(randu(rng, std::log(0.02), std::log(0.15)));
    const int kind = static_cast<int>(randu(rng, 0, 5));
    const cv::Scalar g = grey();
    if (kind == 0) {
      cv::rectangle(tex, c, c + cv::Point(px(size), px(size * randu(rng, 0.3, 1.5))), g, cv::FILLED);
    } else if (kind == 1) {
      const cv::RotatedRect r(cv::Point2f(static_cast<float>(c.x), static_cast<float>(c.y)),
                              cv::Size2f(static_cast<float>(px(size)), static_cast<float>(px(size * randu(rng, 0.3, 1.0)))),
                              static_cast<float>(randu(rng, 0, 180)));
      cv::Point2f v[4];
      r.points(v);
      const cv::Point pts[4] = {v[0], v[1], v[2], v[3]};
      cv::fillConvexPoly(tex, pts, 4, g);
    } else if (kind == 2) {
      cv::circle(tex, c, std::max(1, px(size / 2)), g, cv::FILLED);
    } else if (kind == 3) {
      cv::ellipse(tex, c, cv::Size(std::max(1, px(size / 2)), std::max(1, px(size * randu(rng, 0.15, 0.5)))),
                  randu(rng, 0, 180), 0, 360, g, cv::FILLED);
    } else {
      const cv::Point pts[3] = {c, c + cv::Point(px(size * randu(rng, -1, 1)), px(size * randu(rng, 0.3, 1))),
                                c + cv::Point(px(size * randu(rng, 0.3, 1)), px(size * randu(rng, -1, 1)))};
      cv::fillConvexPoly(tex, pts, 3, g);
    }
  }
  // Small blobs and dots of 0.5–2 cm.
  const int n_small = static_cast<int>(area * 150.0);
  for (int i = 0; i < n_small; ++i) {
    const cv::Point c = random_point();
    const int r = std::max(1, px(randu(rng, 0.0025, 0.01)));
    if (randu(rng, 0, 1) < 0.5)
      cv::circle(tex, c, r, grey(), cv::FILLED);
    else
      cv::rectangle(tex, c - cv::Point(r, r), c + cv::Point(r, r), grey(), cv::FILLED);
  }
  // Grain.
  cv::Mat grain(h, w, CV_16SC1);
  std::int16_t* g = grain.ptr<std::int16_t>();
  for (std::size_t i = 0; i < grain.total(); ++i) g[i] = static_cast<std::int16_t>(std::lround(5.0 * randn(rng)));
  cv::Mat tex16;
  tex.convertTo(tex16, CV_16SC1);
  tex16 += grain;
  tex16.convertTo(tex, CV_8UC1);  // saturating
  return tex;
}

}  // namespace

void World::generate_textures() {
  std::vector<cv::Mat> images;
  if (config_.texture == "images") {
    for (const std::string& path : config_.images) {
      cv::Mat im = io::codecs::imread(path, cv::IMREAD_GRAYSCALE);
      if (im.empty()) throw IoError(fmt::format("world: cannot read texture image '{}'", path));
      images.push_back(im);
    }
  }
  textures_.resize(faces_.size());
  for (std::size_t k = 0; k < faces_.size(); ++k) {
    const Face& f = faces_[k];
    FaceTexture& tex = textures_[k];
    // Faces nobody can see (box bottoms on the floor, pillar ends on floor/ceiling) get a 2x2 texture.
    const bool hidden = k >= 6 && f.axis == 2 &&
                        (std::abs(f.coord - room_min_.z()) < 1e-6f || std::abs(f.coord - room_max_.z()) < 1e-6f);
    const Eigen::Vector2f ext = f.hi - f.lo;
    tex.width = hidden ? 2 : static_cast<int>(std::ceil(ext.x() * inv_texel_)) + 2;
    tex.height = hidden ? 2 : static_cast<int>(std::ceil(ext.y() * inv_texel_)) + 2;
    cv::Mat m;
    if (hidden || config_.texture == "uniform") {
      m = cv::Mat(tex.height, tex.width, CV_8UC1, cv::Scalar(config_.uniform_grey));
    } else if (config_.texture == "images") {
      const cv::Mat& im = images[k % images.size()];
      const int tile_w = std::max(2, static_cast<int>(std::lround(config_.image_tile_size * inv_texel_)));
      const int tile_h = std::max(2, static_cast<int>(std::lround(tile_w * static_cast<double>(im.rows) / im.cols)));
      cv::Mat tile;
      cv::resize(im, tile, cv::Size(tile_w, tile_h), 0, 0, cv::INTER_AREA);
      m = cv::Mat(tex.height, tex.width, CV_8UC1);
      for (int y = 0; y < tex.height; y += tile_h)
        for (int x = 0; x < tex.width; x += tile_w) {
          const cv::Rect r(x, y, std::min(tile_w, tex.width - x), std::min(tile_h, tex.height - y));
          tile(cv::Rect(0, 0, r.width, r.height)).copyTo(m(r));
        }
    } else {
      Rng rng(config_.seed * 1000003ULL + k);
      m = procedural_texture(tex.width, tex.height, config_.texel_size, rng);
    }
    if (!hidden && config_.texture != "uniform") {
      // Baked-in lighting so that faces of different orientation differ in brightness as under a ceiling light:
      // floor darker, ceiling brighter, walls by orientation (uniform textures stay exact for tests).
      static constexpr double kGain[3][2] = {{0.85, 0.95}, {0.9, 0.8}, {0.7, 1.1}};
      m.convertTo(m, CV_8U, kGain[f.axis][k < 6 ? k % 2 : 1 - k % 2]);  // [axis][normal along +axis ? 0 : 1]
    }
    tex.texels.assign(m.datastart, m.dataend);
  }
  samplers_.resize(faces_.size());
  for (std::size_t k = 0; k < faces_.size(); ++k) {
    const Face& f = faces_[k];
    const FaceTexture& tex = textures_[static_cast<std::size_t>(f.texture)];
    RTSLAM_CHECK(tex.width >= 2 && tex.height >= 2, "world: face textures must be at least 2 x 2 texels");
    // trace_avx2 computes texel offsets in 32-bit lanes (the room's texel bound, 4e8, keeps them far below).
    RTSLAM_CHECK(tex.texels.size() < (std::size_t{1} << 31), "world: a face texture has 2^31 texels or more");
    FaceSampler& s = samplers_[k];
    s.b = (f.axis + 1) % 3;
    s.c = (f.axis + 2) % 3;
    s.lo_b = f.lo.x();
    s.lo_c = f.lo.y();
    s.texels = tex.texels.data();
    s.width = static_cast<std::size_t>(tex.width);
    s.x0_max = tex.width - 2;
    s.y0_max = tex.height - 2;
    s.s_max = static_cast<float>(tex.width - 1);
    s.t_max = static_cast<float>(tex.height - 1);
  }
  std::size_t total = 0;
  for (const FaceTexture& t : textures_) total += t.texels.size();
  logger("sim")->debug("world: {} faces, {:.1f} Mtexels", faces_.size(), static_cast<double>(total) * 1e-6);
}

std::vector<Eigen::Vector3d> points_on_box_faces(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int n,
                                                 std::mt19937_64& rng) {
  const Eigen::Vector3d size = hi - lo;
  const double areas[3] = {size.y() * size.z(), size.x() * size.z(), size.x() * size.y()};  // faces ⟂ x, y, z
  const double total = 2.0 * (areas[0] + areas[1] + areas[2]);
  std::vector<Eigen::Vector3d> pts;
  pts.reserve(static_cast<size_t>(std::max(n, 0)));
  for (int i = 0; i < n; ++i) {
    double u = randu(rng, 0.0, total);
    int axis = 0;
    while (axis < 2 && u >= 2.0 * areas[axis]) u -= 2.0 * areas[axis++];
    Eigen::Vector3d p(randu(rng, lo.x(), hi.x()), randu(rng, lo.y(), hi.y()), randu(rng, lo.z(), hi.z()));
    p[axis] = u < areas[axis] ? lo[axis] : hi[axis];
    pts.push_back(p);
  }
  return pts;
}

}  // namespace rtslam::sim
