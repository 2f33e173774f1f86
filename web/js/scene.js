// The 3D view (three.js, bundled from npm into the binary): landmarks with their 3σ principal axes (AHP and
// Euclidean in different colours), the estimated trajectory, the ground truth aligned to the estimate, the camera.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const COLOURS = {
  ahp: new THREE.Color(0xff9a1f),
  euclidean: new THREE.Color(0x3fa9ff),
  unknown: new THREE.Color(0xc8c8c8),
  created: new THREE.Color(0xff00ff),
};
const WHITE = new THREE.Color(0xffffff);

// A line or point set whose buffers grow by doubling.
function growable(itemSize, capacity) {
  const geometry = new THREE.BufferGeometry();
  const set = (cap) => {
    const attr = new THREE.BufferAttribute(new Float32Array(cap * itemSize), itemSize);
    attr.setUsage(THREE.DynamicDrawUsage);
    return attr;
  };
  geometry.setAttribute('position', set(capacity));
  geometry.setDrawRange(0, 0);
  return {
    geometry,
    ensure(n, withColour = false) {
      const cur = geometry.getAttribute('position');
      const hasColour = geometry.getAttribute('color') !== undefined;
      if (cur.count >= n && (!withColour || hasColour)) return;
      let cap = cur.count;
      while (cap < n) cap *= 2;
      if (cap !== cur.count) geometry.setAttribute('position', set(cap));
      if (withColour) geometry.setAttribute('color', set(cap));
    },
  };
}

export class SceneView {
  constructor(container) {
    this.container = container;
    this.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(window.devicePixelRatio || 1);
    this.renderer.setClearColor(0x0d0f11);
    container.appendChild(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(50, 1, 0.01, 2000);
    this.camera.up.set(0, 0, 1);
    this.camera.position.set(6, -6, 5);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.addEventListener('change', () => this.requestRender());
    // The view follows the map (refitted every 3 s) until the user moves it; "fit" refits once.
    this.userMoved = false;
    this.lastFit = 0;
    this.controls.addEventListener('start', () => { this.userMoved = true; });
    this.renders = 0;
    this.landmarksShown = 0;
    this.fitted = false;

    const grid = new THREE.GridHelper(20, 20, 0x2a2e33, 0x202327);
    grid.rotation.x = Math.PI / 2; // the XY plane: z is up (gravity along −z on EuRoC-style rigs)
    this.scene.add(grid);
    this.scene.add(new THREE.AxesHelper(0.5));

    // Landmarks: points and their 3σ axes.
    this.points = growable(3, 1024);
    this.points.ensure(1024, true);
    this.pointsObj = new THREE.Points(this.points.geometry,
      new THREE.PointsMaterial({ size: 5, sizeAttenuation: false, vertexColors: true }));
    this.scene.add(this.pointsObj);
    this.axes = growable(3, 6 * 1024);
    this.axes.ensure(6 * 1024, true);
    this.axesObj = new THREE.LineSegments(this.axes.geometry,
      new THREE.LineBasicMaterial({ vertexColors: true, transparent: true, opacity: 0.45 }));
    this.scene.add(this.axesObj);

    // Trajectory and ground truth.
    this.traj = growable(3, 4096);
    this.trajObj = new THREE.Line(this.traj.geometry, new THREE.LineBasicMaterial({ color: 0xff4d4d }));
    this.scene.add(this.trajObj);
    this.gt = growable(3, 16);
    this.gtTimes = [];
    this.gtObj = new THREE.Line(this.gt.geometry, new THREE.LineBasicMaterial({ color: 0xd0d0d0, transparent: true, opacity: 0.7 }));
    this.gtObj.matrixAutoUpdate = false;
    this.scene.add(this.gtObj);

    // Camera frustum (live: T_WS) and robot axes (replay: T_WR).
    this.frustum = new THREE.LineSegments(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color: 0xffffff }));
    this.frustum.matrixAutoUpdate = false;
    this.frustum.visible = false;
    this.scene.add(this.frustum);
    this.robot = new THREE.AxesHelper(0.3);
    this.robot.matrixAutoUpdate = false;
    this.robot.visible = false;
    this.scene.add(this.robot);

    this.resize();
    new ResizeObserver(() => this.resize()).observe(container);
  }

  resize() {
    const w = this.container.clientWidth || 400, h = this.container.clientHeight || 300;
    this.renderer.setSize(w, h, false);
    this.renderer.domElement.style.width = '100%';
    this.renderer.domElement.style.height = '100%';
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.requestRender();
  }

  requestRender() {
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      this.renderer.render(this.scene, this.camera);
      this.renders += 1;
    });
  }

  // rows: [id, type (1 Euclidean, 0 AHP, −1 unknown), x, y, z, a1(3), a2(3), a3(3), flags (1 updated, 2 matched, 4 new)]
  setLandmarks(rows) {
    const n = rows.length;
    this.points.ensure(n, true);
    this.axes.ensure(6 * n, true);
    const pp = this.points.geometry.getAttribute('position'), pc = this.points.geometry.getAttribute('color');
    const ap = this.axes.geometry.getAttribute('position'), ac = this.axes.geometry.getAttribute('color');
    const col = new THREE.Color();
    for (let i = 0; i < n; ++i) {
      const r = rows[i];
      const flags = r[14];
      col.copy(flags & 4 ? COLOURS.created : r[1] === 1 ? COLOURS.euclidean : r[1] === 0 ? COLOURS.ahp : COLOURS.unknown);
      if (flags & 1) col.lerp(WHITE, 0.45);
      pp.setXYZ(i, r[2], r[3], r[4]);
      pc.setXYZ(i, col.r, col.g, col.b);
      for (let k = 0; k < 3; ++k) {
        const ax = r[5 + 3 * k], ay = r[6 + 3 * k], az = r[7 + 3 * k];
        const j = 6 * i + 2 * k;
        ap.setXYZ(j, r[2] - ax, r[3] - ay, r[4] - az);
        ap.setXYZ(j + 1, r[2] + ax, r[3] + ay, r[4] + az);
        ac.setXYZ(j, col.r, col.g, col.b);
        ac.setXYZ(j + 1, col.r, col.g, col.b);
      }
    }
    pp.needsUpdate = pc.needsUpdate = ap.needsUpdate = ac.needsUpdate = true;
    this.points.geometry.setDrawRange(0, n);
    this.axes.geometry.setDrawRange(0, 6 * n);
    this.points.geometry.computeBoundingSphere();
    this.landmarksShown = n;
    if (n >= 10 && !this.userMoved && performance.now() - this.lastFit > 3000) this.fit();
    this.requestRender();
  }

  // positions: flat [x0, y0, z0, x1, ...]; count: poses to draw.
  setTrajectory(positions, count) {
    this.traj.ensure(Math.max(count, 1));
    const a = this.traj.geometry.getAttribute('position');
    for (let i = 0; i < count; ++i) a.setXYZ(i, positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]);
    a.needsUpdate = true;
    this.traj.geometry.setDrawRange(0, count);
    this.traj.geometry.computeBoundingSphere();
    this.requestRender();
  }

  setGroundTruth(gt) {
    if (!gt) return;
    const n = gt.t.length;
    this.gt.ensure(Math.max(n, 1));
    const a = this.gt.geometry.getAttribute('position');
    for (let i = 0; i < n; ++i) a.setXYZ(i, gt.p[3 * i], gt.p[3 * i + 1], gt.p[3 * i + 2]);
    a.needsUpdate = true;
    this.gt.geometry.computeBoundingSphere();
    this.gtTimes = gt.t;
    this.gt.geometry.setDrawRange(0, 0);
    this.requestRender();
  }

  // x ↦ s R x + t, mapping the ground truth into the estimate's frame.
  setAlignment(a) {
    const R = a.R, s = a.s;
    this.gtObj.matrix.set(
      s * R[0], s * R[1], s * R[2], a.t[0],
      s * R[3], s * R[4], s * R[5], a.t[1],
      s * R[6], s * R[7], s * R[8], a.t[2],
      0, 0, 0, 1);
    this.gtObj.matrixWorldNeedsUpdate = true;
    this.requestRender();
  }

  // The ground truth is drawn up to time t (s).
  setTime(t) {
    const ts = this.gtTimes;
    let lo = 0, hi = ts.length;
    while (lo < hi) { const mid = (lo + hi) >> 1; if (ts[mid] <= t) lo = mid + 1; else hi = mid; }
    this.gt.geometry.setDrawRange(0, lo);
    this.requestRender();
  }

  static matrixOf(pose) {
    const q = new THREE.Quaternion(pose.q[1], pose.q[2], pose.q[3], pose.q[0]); // pose.q is [w x y z]
    return new THREE.Matrix4().compose(new THREE.Vector3(...pose.p), q, new THREE.Vector3(1, 1, 1));
  }

  // T_WS and the pinhole parameters: a frustum of depth `depth` m (z forward, x right, y down).
  setCamera(T_WS, cam, depth = 0.25) {
    const w = cam && cam.width > 0 ? cam.width : 640, h = cam && cam.height > 0 ? cam.height : 480;
    const fx = cam && cam.fx > 0 ? cam.fx : w, fy = cam && cam.fy > 0 ? cam.fy : w;
    const cx = cam && cam.fx > 0 ? cam.cx : w / 2, cy = cam && cam.fy > 0 ? cam.cy : h / 2;
    const c = [[0, 0], [w, 0], [w, h], [0, h]].map(([u, v]) => [((u - cx) / fx) * depth, ((v - cy) / fy) * depth, depth]);
    const v = [];
    for (let i = 0; i < 4; ++i) v.push(0, 0, 0, ...c[i], ...c[i], ...c[(i + 1) % 4]);
    v.push(...c[0], c[0][0] + (c[1][0] - c[0][0]) / 2, c[0][1] - depth * 0.15, depth); // "up" tick
    this.frustum.geometry.setAttribute('position', new THREE.Float32BufferAttribute(v, 3));
    this.frustum.matrix.copy(SceneView.matrixOf(T_WS));
    this.frustum.matrixWorldNeedsUpdate = true;
    this.frustum.visible = true;
    this.requestRender();
  }

  setRobot(T_WR) {
    this.robot.matrix.copy(SceneView.matrixOf(T_WR));
    this.robot.matrixWorldNeedsUpdate = true;
    this.robot.visible = true;
    this.requestRender();
  }

  // Frames the landmarks and the trajectory (robust to far outliers: the 90 % nearest points to the median).
  fit() {
    const pts = [];
    const pp = this.points.geometry.getAttribute('position');
    const n = this.points.geometry.drawRange.count;
    for (let i = 0; i < n; ++i) pts.push(new THREE.Vector3(pp.getX(i), pp.getY(i), pp.getZ(i)));
    const tp = this.traj.geometry.getAttribute('position');
    for (let i = 0; i < this.traj.geometry.drawRange.count; ++i) pts.push(new THREE.Vector3(tp.getX(i), tp.getY(i), tp.getZ(i)));
    if (pts.length === 0) return;
    const med = (k) => pts.map((p) => p.getComponent(k)).sort((a, b) => a - b)[pts.length >> 1];
    const centre = new THREE.Vector3(med(0), med(1), med(2));
    const d = pts.map((p) => p.distanceTo(centre)).sort((a, b) => a - b);
    const radius = Math.max(0.5, d[Math.floor(0.9 * (d.length - 1))]);
    this.controls.target.copy(centre);
    const dir = new THREE.Vector3(1, -1.2, 0.9).normalize();
    this.camera.position.copy(centre).addScaledVector(dir, radius * 2.4);
    this.camera.near = radius / 100;
    this.camera.far = radius * 200;
    this.camera.updateProjectionMatrix();
    this.controls.update();
    this.fitted = true;
    this.lastFit = performance.now();
    this.requestRender();
  }
}
