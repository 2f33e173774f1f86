#pragma once
// Synthetic worlds: a closed axis-aligned room (floor, ceiling, four walls) containing axis-aligned boxes and
// pillars, every face textured. Textures are procedural (seeded, multi-scale: poster-sized rectangles, objects of
// a few centimetres, small blobs, grain, so that Harris corners are plentiful and not repetitive), uniform grey
// (for tests), or image files given by the user (tiled at a physical size). Small analytic disc markers can be
// added for geometry tests.
//
// Frames: W, z up; the room spans [cx - sx/2, cx + sx/2] x [cy - sy/2, cy + sy/2] x [floor, floor + sz], with
// (cx, cy) = room.center (default 0) and floor = room.floor (default 0). Box and pillar centres are given relative
// to the room centre. Lengths in metres.
//
// YAML (all keys optional; unknown keys are errors):
//   seed: 1                   # texture and random-box layout
//   room: {size: [8, 6, 3], center: [0, 0], floor: 0}
//   texel_size: 0.005         # m per texel
//   texture: procedural       # procedural | uniform | images
//   uniform_grey: 128         # texture: uniform
//   images: [a.png, b.jpg]    # texture: images (grey; face k uses image k mod n)
//   image_tile_size: 1.0      # m covered by one image tile's width
//   boxes: [{center: [x, y], size: [sx, sy, sz]}]   # standing on the floor
//   pillars: [{center: [x, y], size: [sx, sy]}]     # floor to ceiling
//   random_boxes: 0           # extra boxes placed at random (seeded), away from the room centre
#include <cstdint>
#include <random>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace rtslam {
class YamlMap;
}

namespace rtslam::sim {

struct BoxSpec {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();    // x, y of the footprint centre, from the room centre (m)
  Eigen::Vector3d size = Eigen::Vector3d(0.5, 0.5, 0.5);  // m
};

struct WorldConfig {
  std::uint64_t seed = 1;
  Eigen::Vector3d room_size = Eigen::Vector3d(8.0, 6.0, 3.0);
  Eigen::Vector2d room_center = Eigen::Vector2d::Zero();
  double floor_z = 0.0;
  double texel_size = 0.005;
  std::string texture = "procedural";
  int uniform_grey = 128;
  std::vector<std::string> images;
  double image_tile_size = 1.0;
  std::vector<BoxSpec> boxes;    // on the floor
  std::vector<BoxSpec> pillars;  // size.z ignored: floor to ceiling
  int random_boxes = 0;

  /// Reads the keys documented above from `map` and checks the whole mapping (unknown keys are errors).
  static WorldConfig from_yaml(YamlMap& map);
  static WorldConfig from_file(const std::string& path);
  /// Built-in worlds: "room" (8x6x3 m, boxes and pillars), "small-room" (5x4x2.6 m), "hall" (16x12x5 m).
  static WorldConfig preset(const std::string& name);
  static std::vector<std::string> preset_names();
  /// ConfigError naming `where`, the key and the bound.
  void validate(const std::string& where) const;
  /// Grows the room (keeping at least its size) so that every point lies at least `margin` inside it, recentring
  /// it on the points' bounding box; boxes and pillars closer than `clearance` to a point are removed. Returns
  /// the number of obstacles removed. For worlds around recorded trajectories (follow:FILE).
  int fit_to_points(const std::vector<Eigen::Vector3d>& points, double margin, double clearance);
};

/// A texture image of one face: grey levels, texel (0, 0) at the face's minimum corner.
struct FaceTexture {
  int width = 0, height = 0;
  std::vector<std::uint8_t> texels;  // row-major
  /// Bilinear sample at texel coordinates (s, t) (clamped to the texture).
  float sample(float s, float t) const;
};

/// A small flat disc painted on a surface (for geometry tests): every hit within `radius` of `center` gets
/// `grey`, whatever the texture.
struct Marker {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double radius = 0.01;
  float grey = 255.0f;
};

/// The closest surface along a ray.
struct Hit {
  float t = 0.0f;   // distance along the (not necessarily unit) direction
  int face = -1;    // index into World::faces()
};

/// An axis-aligned face: normal along `axis`, plane coordinate `coord`, rectangle lo..hi on the two other axes
/// ((axis+1)%3, (axis+2)%3).
struct Face {
  int axis = 0;
  float coord = 0.0f;
  Eigen::Vector2f lo = Eigen::Vector2f::Zero(), hi = Eigen::Vector2f::Zero();
  int texture = 0;
};

/// An obstacle (box or pillar) as an axis-aligned box [lo, hi] in W; its six faces are
/// World::faces()[first_face + 2·axis + side] (side 0: the lo plane, 1: the hi plane).
struct Aabb {
  Eigen::Vector3f lo = Eigen::Vector3f::Zero(), hi = Eigen::Vector3f::Zero();
  int first_face = 0;
};

class World {
 public:
  /// Builds the geometry and generates the textures (procedural textures take ~1 s per 100 m² at 5 mm texels).
  explicit World(const WorldConfig& config);

  const WorldConfig& config() const { return config_; }
  Eigen::Vector3d room_min() const { return room_min_.cast<double>(); }
  Eigen::Vector3d room_max() const { return room_max_.cast<double>(); }
  const std::vector<Face>& faces() const { return faces_; }
  /// The obstacles (boxes, then pillars, then random boxes).
  const std::vector<Aabb>& boxes() const { return boxes_; }
  const std::vector<FaceTexture>& textures() const { return textures_; }
  std::vector<Marker>& markers() { return markers_; }
  const std::vector<Marker>& markers() const { return markers_; }

  /// True if p is inside the room and outside every box (with a clearance in m).
  bool is_free(const Eigen::Vector3d& p_W, double clearance = 0.0) const;

  /// Closest hit of the ray o + t·d (t > 0) from a point inside the room. Always hits (the room is closed)
  /// unless o is outside the room.
  bool cast(const Eigen::Vector3f& o, const Eigen::Vector3f& d, Hit& hit) const;
  /// The same, considering only the obstacles listed (indices into boxes()): the renderer passes those that
  /// can be in view of a block of pixels. Identical to cast() when every obstacle the ray hits is listed.
  bool cast(const Eigen::Vector3f& o, const Eigen::Vector3f& d, std::span<const int> boxes, Hit& hit) const;
  /// Grey level at a hit point p on a face (bilinear texture sample, markers on top).
  float shade(int face, const Eigen::Vector3f& p) const;
  /// Rays o_k + t·d_k by coordinate: o[i][k] is coordinate i of ray k's origin, k < size.
  struct Rays {
    const float* o[3];
    const float* d[3];
    std::size_t size;
  };
  /// Grey levels seen along the rays: grey[k] = shade() at the closest hit of cast(o_k, d_k, boxes, ·), 0 if none.
  /// The renderer's call, one per tile of pixels.
  /// On x86-64 CPUs with AVX2 the rays go eight at a time (the same float operations in the same order: the same
  /// grey levels, bit for bit, as one at a time); rays with a zero direction component, worlds with markers and
  /// other CPUs take the plain path.
  void trace(const Rays& rays, std::span<const int> boxes, float* grey) const;
  /// Lets trace() use its AVX2 path when the CPU has it (default), or not (tests compare the two). Not while a
  /// renderer of this world is rendering.
  void set_vectorized(bool enabled) { vectorized_ = enabled; }
  /// Whether trace() takes its AVX2 path for a world without markers.
  bool vectorized() const;

 private:
  // Per face, what shade() needs (texture axes, origin, sizes), precomputed; textures are at least 2 x 2 texels.
  struct FaceSampler {
    int b = 1, c = 2;             // texture axes: (axis + 1) % 3, (axis + 2) % 3
    float lo_b = 0.0f, lo_c = 0.0f;
    const std::uint8_t* texels = nullptr;
    std::size_t width = 0;
    int x0_max = 0, y0_max = 0;   // width - 2, height - 2
    float s_max = 0.0f, t_max = 0.0f;  // width - 1, height - 1
  };
  // The bodies of cast() and shade(), forced inline into trace() (the renderer's per-ray work): GCC does not
  // inline the public functions themselves (-fPIC makes them interposable); inlined, a frame takes ~25 % less time.
  bool cast_ray(const Eigen::Vector3f& o, const Eigen::Vector3f& d, std::span<const int> boxes, Hit& hit) const;
  float shade_hit(int face, const Eigen::Vector3f& p) const;
  void cast_boxes_parallel(const Eigen::Vector3f& o, const Eigen::Vector3f& d, std::span<const int> boxes,
                           float& best, int& face) const;
  // One ray of trace(): cast_ray, then shade_hit at the hit (forced inline too).
  float trace_ray(const Eigen::Vector3f& o, const Eigen::Vector3f& d, std::span<const int> boxes) const;
  // The AVX2 path of trace() over the first multiple of 8 rays; returns how many it traced.
  std::size_t trace_avx2(const Rays& rays, std::span<const int> boxes, float* grey) const;
  void add_faces(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi);
  void generate_textures();

  WorldConfig config_;
  Eigen::Vector3f room_min_, room_max_;
  std::vector<Aabb> boxes_;
  std::vector<int> all_boxes_;  // 0, 1, ..., boxes_.size() - 1
  std::vector<Face> faces_;
  std::vector<FaceTexture> textures_;
  std::vector<FaceSampler> samplers_;  // [face]
  bool vectorized_ = true;
  std::vector<Marker> markers_;
  float inv_texel_ = 200.0f;
};

/// `n` points spread uniformly over the six faces of the box [lo, hi] (by area): the known-point world of the
/// points demo (sim/point_scene.hpp), drawn from `rng`.
std::vector<Eigen::Vector3d> points_on_box_faces(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int n,
                                                 std::mt19937_64& rng);

}  // namespace rtslam::sim
