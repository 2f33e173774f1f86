// rtslam viewer page: talks to rtslam::viz::Viewer over a WebSocket (/ws).
// Server → page (JSON text unless said): hello {mode, title, three, finished, nees_band, gt, [overlays, summary,
// camera, map_types_known]}; history {entries: [{i, t, p, q, sp, n, ms, nis, nisb, nees}]}; align {method, s, R,
// t}; frame {i, t, T_WR, T_WS, camera, landmarks, n, image: bytes, [final]} followed by a binary JPEG when
// image > 0; status {finished, pushed, dropped}. Page → server: "ack" once a frame is shown.
// window.rtslamViewer exposes counters for tests (frames, images shown, 3D renders, landmarks drawn).
import { LinePlot } from './plots.js';

const $ = (id) => document.getElementById(id);
const probe = {
  connected: false, mode: null, finished: false, framesReceived: 0, imagesShown: 0, lastImageFrame: -1,
  landmarkCount: 0, landmarksShown: 0, historyLength: 0, sceneReady: false, sceneError: null, sceneRenders: 0,
  dropped: 0, lastFrame: -1,
};
window.rtslamViewer = probe;

const state = {
  mode: null, history: [], gt: null, overlays: [], overlayByIndex: new Map(), frameMeta: null, nees_band: null,
  latestFrame: null, replayIndex: 0, playing: false, cameraInfo: null,
};
let scene = null;
let ws = null;

// ---- 3D view (three.js is optional: a build without npm has none) ------------------------------------------------
async function loadScene(available) {
  if (scene || probe.sceneError) return;
  if (!available) {
    probe.sceneError = 'three.js was not bundled into this build (npm was not available): no 3D view';
    $('scene-note').textContent = probe.sceneError;
    return;
  }
  try {
    const { SceneView } = await import('./scene.js');
    scene = new SceneView($('scene'));
    probe.sceneReady = true;
    $('scene-note').hidden = true;
    refreshScene(true);
  } catch (e) {
    probe.sceneError = String(e && e.message ? e.message : e);
    $('scene-note').textContent = `3D view unavailable: ${probe.sceneError}`;
  }
}
setInterval(() => { if (scene) probe.sceneRenders = scene.renders; }, 100);

function trajectoryUpTo(count) {
  const pos = new Float32Array(3 * count);
  for (let i = 0; i < count; ++i) pos.set(state.history[i].p, 3 * i);
  return pos;
}

function refreshScene(all = false) {
  if (!scene) return;
  if (all && state.gt) scene.setGroundTruth(state.gt);
  if (all && state.align) scene.setAlignment(state.align);
  const count = state.mode === 'replay' ? Math.min(state.replayIndex + 1, state.history.length) : state.history.length;
  scene.setTrajectory(trajectoryUpTo(count), count);
  const h = state.history[count - 1];
  if (h) scene.setTime(h.t);
  if (state.latestFrame && state.latestFrame.landmarks) {
    scene.setLandmarks(state.latestFrame.landmarks);
    probe.landmarksShown = scene.landmarksShown;
  }
  if (state.mode === 'live' && state.latestFrame && state.latestFrame.T_WS) {
    scene.setCamera(state.latestFrame.T_WS, state.latestFrame.camera);
  } else if (h) {
    scene.setRobot({ p: h.p, q: h.q });
  }
}

// ---- image ----------------------------------------------------------------------------------------------------
async function showImage(blob, frameIndex) {
  const bmp = await createImageBitmap(blob);
  const c = $('image');
  if (c.width !== bmp.width || c.height !== bmp.height) { c.width = bmp.width; c.height = bmp.height; }
  c.getContext('2d').drawImage(bmp, 0, 0);
  bmp.close();
  $('image-note').hidden = true;
  probe.imagesShown += 1;
  probe.lastImageFrame = frameIndex;
}

// ---- plots ----------------------------------------------------------------------------------------------------
const plots = {
  matches: new LinePlot($('plot-matches'), {
    title: 'matches per frame',
    series: [
      { label: 'visible', color: '#6b7078' }, { label: 'matched', color: '#3fa9ff' },
      { label: 'RANSAC inliers', color: '#ffff00' }, { label: 'updated', color: '#00ff00' },
    ],
  }),
  consistency: new LinePlot($('plot-consistency'), {
    title: 'NEES (pose) / NIS (mean)', log: true,
    series: [
      { label: 'NEES', color: '#c77dff', width: 1.4 }, { label: '99%', color: '#c77dff', dashed: true, legend: false },
      { label: '', color: '#c77dff', dashed: true, legend: false },
      { label: 'NIS', color: '#2ec4b6' }, { label: '', color: '#2ec4b680', dashed: true, legend: false },
      { label: '', color: '#2ec4b680', dashed: true, legend: false },
    ],
  }),
  time: new LinePlot($('plot-time'), { title: 'per-frame time [ms]', series: [{ label: 'SLAM', color: '#ff4d4d' }] }),
};
let plotTimer = null;
function schedulePlots() {
  if (plotTimer) return;
  plotTimer = setTimeout(() => { plotTimer = null; drawPlots(); }, 200);
}
function drawPlots() {
  const H = state.history;
  const x = H.map((h) => h.t);
  const col = (k) => H.map((h) => (h.n ? h.n[k] : null));
  const cursor = state.mode === 'replay' && H[state.replayIndex] ? H[state.replayIndex].t : null;
  plots.matches.draw(x, [col(0), col(2), col(3), col(4)], cursor);
  const nb = state.nees_band || [null, null];
  plots.consistency.draw(x, [
    H.map((h) => (h.nees === undefined ? null : h.nees)), H.map(() => nb[0]), H.map(() => nb[1]),
    H.map((h) => (h.nis === undefined ? null : h.nis)),
    H.map((h) => (h.nisb ? h.nisb[0] : null)), H.map((h) => (h.nisb ? h.nisb[1] : null)),
  ], cursor);
  plots.time.draw(x, [H.map((h) => (h.ms === undefined ? null : h.ms))], cursor);
}
window.addEventListener('resize', schedulePlots);

// ---- header ---------------------------------------------------------------------------------------------------
function setHeader(h, landmarks) {
  if (h) {
    $('frame-index').textContent = h.i;
    $('frame-time').textContent = h.t.toFixed(3);
    $('matched-count').textContent = h.n ? h.n[2] : '—';
  }
  if (landmarks !== undefined) $('landmark-count').textContent = landmarks;
}
function setConnection(text, cls) {
  const el = $('connection');
  el.textContent = text;
  el.className = `badge ${cls}`;
}

// ---- replay ---------------------------------------------------------------------------------------------------
function showReplayFrame(k) {
  state.replayIndex = Math.max(0, Math.min(k, state.history.length - 1));
  const h = state.history[state.replayIndex];
  $('slider').value = String(state.replayIndex);
  if (!h) return;
  $('slider-label').textContent = `frame ${h.i} · ${h.t.toFixed(3)} s · ${state.replayIndex + 1}/${state.history.length}`;
  setHeader(h);
  refreshScene();
  schedulePlots();
  const ov = state.overlayByIndex.get(h.i);
  if (ov !== undefined) {
    fetch(`/api/overlay/${h.i}`).then((r) => (r.ok ? r.blob() : Promise.reject(new Error(r.statusText))))
      .then((b) => showImage(b, h.i)).catch(() => {});
  } else if (state.overlays.length === 0) {
    $('image-note').textContent = 'this run wrote no overlays (rtslam run --overlays DIR, then rtslam view OUT --overlays DIR)';
  }
}
$('slider').addEventListener('input', (e) => { state.playing = false; $('play').textContent = '▶'; showReplayFrame(Number(e.target.value)); });
$('play').addEventListener('click', () => {
  state.playing = !state.playing;
  $('play').textContent = state.playing ? '❚❚' : '▶';
  if (state.playing && state.replayIndex >= state.history.length - 1) showReplayFrame(0);
  const step = () => {
    if (!state.playing) return;
    if (state.replayIndex >= state.history.length - 1) { state.playing = false; $('play').textContent = '▶'; return; }
    showReplayFrame(state.replayIndex + 1);
    setTimeout(step, 50);
  };
  step();
});
$('fit').addEventListener('click', () => { if (scene) { scene.userMoved = false; scene.fit(); } });

// ---- messages ---------------------------------------------------------------------------------------------------
let pendingFrame = null; // frame message waiting for its JPEG

function onHello(m) {
  state.mode = m.mode;
  state.history = [];
  state.gt = m.gt;
  state.align = null;
  state.nees_band = m.nees_band;
  state.latestFrame = null;
  state.overlays = m.overlays || [];
  state.overlayByIndex = new Map(state.overlays.map(([i, t]) => [i, t]));
  probe.mode = m.mode;
  probe.finished = !!m.finished;
  $('title').textContent = m.title || '(untitled run)';
  document.title = `rtslam · ${m.title || m.mode}`;
  const badge = $('mode');
  badge.textContent = m.mode === 'replay' ? 'replay' : m.finished ? 'finished' : 'live';
  badge.className = `badge ${m.mode === 'replay' || m.finished ? 'done' : 'on'}`;
  $('replay-bar').hidden = m.mode !== 'replay';
  $('legend-unknown').hidden = !(m.mode === 'replay' && !m.map_types_known);
  if (m.mode === 'replay' && state.overlays.length === 0) {
    $('image-note').textContent = 'this run wrote no overlays (rtslam run --overlays DIR)';
  }
  loadScene(m.three).then(() => refreshScene(true));
}

function onHistory(m) {
  for (const e of m.entries) state.history.push(e);
  probe.historyLength = state.history.length;
  if (state.mode === 'replay') {
    $('slider').max = String(Math.max(0, state.history.length - 1));
    showReplayFrame(state.history.length - 1);
  } else {
    setHeader(state.history[state.history.length - 1]);
    schedulePlots();
  }
}

function onFrame(m) {
  probe.framesReceived += 1;
  probe.lastFrame = m.i;
  state.latestFrame = m;
  probe.landmarkCount = m.landmarks.length;
  setHeader(null, m.landmarks.length);
  refreshScene();
  if (m.image > 0) pendingFrame = m;
  else if (state.mode === 'live') ws.send('ack');
}

function onMessage(ev) {
  if (typeof ev.data !== 'string') {
    const m = pendingFrame;
    pendingFrame = null;
    const blob = new Blob([ev.data], { type: 'image/jpeg' });
    showImage(blob, m ? m.i : -1).catch(() => {}).finally(() => ws && ws.readyState === 1 && ws.send('ack'));
    return;
  }
  const m = JSON.parse(ev.data);
  switch (m.type) {
    case 'hello': onHello(m); break;
    case 'history': onHistory(m); break;
    case 'align':
      state.align = m;
      $('align-method').textContent = `${m.method}-aligned`;
      if (scene) scene.setAlignment(m);
      break;
    case 'frame': onFrame(m); break;
    case 'status':
      probe.finished = !!m.finished;
      probe.dropped = m.dropped || 0;
      $('dropped-count').textContent = probe.dropped;
      if (m.finished && state.mode === 'live') { $('mode').textContent = 'finished'; $('mode').className = 'badge done'; }
      break;
    default: break;
  }
}

function connect() {
  ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = 'arraybuffer';
  ws.onopen = () => { probe.connected = true; setConnection('connected', 'on'); };
  ws.onmessage = onMessage;
  ws.onclose = () => {
    probe.connected = false;
    setConnection('offline', 'off');
    setTimeout(connect, 1000);
  };
}
setInterval(() => { if (ws && ws.readyState === 1) ws.send('ping'); }, 5000);
setInterval(() => {
  fetch('/api/status').then((r) => r.json()).then((s) => { probe.dropped = s.dropped; $('dropped-count').textContent = s.dropped; })
    .catch(() => {});
}, 2000);
connect();
