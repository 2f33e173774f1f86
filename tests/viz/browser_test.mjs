// Browser tests of the web viewer (docs/viewer.md), driven by playwright-core in Debian's headless Chromium.
//
//   node browser_test.mjs live   --cli BIN --node-modules DIR --out DIR [--chromium PATH] [--duration S] [--seed N]
//   node browser_test.mjs replay --live-run BIN --cli BIN --node-modules DIR --out DIR [--chromium PATH]
//
// live:   starts BIN (viz_live_run: a 4 s simulated run feeding the viewer, the stand-in for `rtslam run --view`),
//         loads the page, checks that the image and the 3D view update while the run goes, that the page shows
//         as many landmarks as the run ends with, and saves OUT/viewer_live.png.
// replay: writes a run folder with `rtslam run --duration 3 --out`, its overlays with BIN --overlays (same config
//         and seed: the same frames), serves it with `rtslam view`, checks the trajectory, the map, the image and
//         the 3D view at two slider positions, and saves OUT/viewer_replay.png.
// Exit 0: passed; 1: failed (the reason on stderr); 77: skipped (no Chromium or no playwright-core).
import { spawn, spawnSync } from 'node:child_process';
import { createRequire } from 'node:module';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import readline from 'node:readline';

const SKIP = 77;
const mode = process.argv[2];
const args = {};
for (let i = 3; i < process.argv.length; i += 2) args[process.argv[i].replace(/^--/, '')] = process.argv[i + 1];
const chromiumPath = args.chromium || '/usr/bin/chromium';

function skip(why) {
  console.log(`SKIPPED: ${why}`);
  process.exit(SKIP);
}
function fail(why) {
  console.error(`FAILED: ${why}`);
  process.exitCode = 1;
  throw new Error(why);
}
function check(cond, what) {
  if (!cond) fail(what);
  console.log(`ok: ${what}`);
}

if (mode !== 'live' && mode !== 'replay') {
  console.error('usage: node browser_test.mjs live|replay --live-run BIN [--cli BIN] --node-modules DIR --out DIR');
  process.exit(2);
}
if (!fs.existsSync(chromiumPath)) skip(`${chromiumPath} not found (Debian package chromium)`);
let chromium;
try {
  const require = createRequire(path.join(path.resolve(args['node-modules'] || '.'), 'noop.js'));
  ({ chromium } = require('playwright-core'));
} catch (e) {
  skip(`playwright-core not installed in ${args['node-modules']} (npm ci in the build's web/ folder): ${e.message}`);
}
fs.mkdirSync(args.out, { recursive: true });

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
async function until(what, fn, timeoutMs = 60000, stepMs = 100) {
  const t0 = Date.now();
  for (;;) {
    const v = await fn();
    if (v) return v;
    if (Date.now() - t0 > timeoutMs) fail(`timed out after ${timeoutMs / 1000} s waiting for ${what}`);
    await sleep(stepMs);
  }
}

// Starts a process and collects its stdout lines.
function start(cmd, argv) {
  const child = spawn(cmd, argv, { stdio: ['pipe', 'pipe', 'inherit'] });
  const lines = [];
  readline.createInterface({ input: child.stdout }).on('line', (l) => { lines.push(l); console.log(`[${path.basename(cmd)}] ${l}`); });
  const exited = new Promise((resolve) => child.on('exit', (code, signal) => resolve({ code, signal })));
  return { child, lines, exited };
}
const lineWith = (proc, prefix) => proc.lines.find((l) => l.startsWith(prefix));

async function launch() {
  const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'rtslam-viewer-chromium-'));
  const context = await chromium.launchPersistentContext(userDataDir, {
    executablePath: chromiumPath,
    headless: true,
    viewport: { width: 1500, height: 1000 },
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync',
      '--enable-unsafe-swiftshader', '--use-angle=swiftshader'],
  });
  const page = context.pages()[0] || (await context.newPage());
  page.on('console', (m) => { if (m.type() === 'error') console.log(`[page] ${m.text()}`); });
  page.on('pageerror', (e) => console.log(`[page error] ${e.message}`));
  return { context, page, userDataDir };
}
const probe = (page) => page.evaluate(() => ({ ...window.rtslamViewer }));

// Counts overlay-coloured pixels (the legend's yellow, green, blue, red) in the page's image canvas.
const overlayPixels = (page) => page.evaluate(() => {
  const c = document.getElementById('image');
  const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  let coloured = 0, nonBlack = 0;
  for (let i = 0; i < d.length; i += 4) {
    const [r, g, b] = [d[i], d[i + 1], d[i + 2]];
    if (r + g + b > 30) nonBlack += 1;
    if (Math.max(r, g, b) - Math.min(r, g, b) > 120) coloured += 1;
  }
  return { coloured, nonBlack, total: d.length / 4 };
});

async function liveTest() {
  // The user's command: `rtslam run --view` on a short simulated run; --view-wait so that the page sees it from its
  // first frame, --view-hold so that it can be checked after the run (SIGTERM ends it).
  const runDir = path.join(args.out, 'live-run');
  fs.rmSync(runDir, { recursive: true, force: true });
  const run = start(args.cli, ['run', '--config', 'config/sim_mono.yaml', '--duration', args.duration || '4',
    '--seed', args.seed || '1', '--out', runDir, '--view', '127.0.0.1:0', '--view-wait', '60', '--view-hold', '300']);
  let browser;
  try {
    const urlLine = await until('the viewer URL', () => lineWith(run, 'viewer: http'), 60000);
    const url = urlLine.slice('viewer: '.length).trim();
    check(/^http:\/\/127\.0\.0\.1:\d+\/$/.test(url), `the viewer serves on loopback (${url})`);
    browser = await launch();
    const { page } = browser;
    await page.goto(url);
    await until('the page to connect', async () => (await probe(page)).connected, 30000);
    const p0 = await until('a first image', async () => { const p = await probe(page); return p.imagesShown >= 1 && p; }, 60000);
    check(p0.sceneReady, `the 3D view loaded (three.js bundled)${p0.sceneError ? `: ${p0.sceneError}` : ''}`);
    // While the run goes: the image and the 3D view update.
    const p1 = await until('more images while the run goes', async () => {
      const p = await probe(page);
      return p.imagesShown >= p0.imagesShown + 3 && p.lastImageFrame > p0.lastImageFrame && p;
    }, 60000);
    check(p1.lastImageFrame > p0.lastImageFrame, `the image updates (frame ${p0.lastImageFrame} → ${p1.lastImageFrame}, ${p1.imagesShown} images)`);
    check(p1.sceneRenders > p0.sceneRenders, `the 3D view updates (${p0.sceneRenders} → ${p1.sceneRenders} renders)`);
    const liveResultSeen = !lineWith(run, 'viewer: the run has ended');
    check(liveResultSeen, 'those updates came while the run was still going');

    await until('the end of the run', () => lineWith(run, 'viewer: the run has ended'), 120000);
    const summary = JSON.parse(fs.readFileSync(path.join(runDir, 'summary.json'), 'utf8'));
    const frames = Number(summary.frames), landmarks = Number(summary.landmarks.final);
    const viewerStats = (summary.viz && summary.viz.viewer) || {};
    const pf = await until('the page to show the last frame', async () => {
      const p = await probe(page);
      return p.finished && p.lastFrame === frames - 1 && p.imagesShown > 0 && p.lastImageFrame === frames - 1 && p;
    }, 60000);
    check(pf.landmarksShown === landmarks, `the 3D view shows the run's ${landmarks} landmarks (shows ${pf.landmarksShown})`);
    const text = await page.textContent('#landmark-count');
    check(Number(text) === landmarks, `the header says ${landmarks} landmarks (says ${text})`);
    check(pf.historyLength === frames, `the trajectory has every frame (${pf.historyLength} of ${frames})`);
    const px = await overlayPixels(page);
    check(px.nonBlack > 0.5 * px.total && px.coloured > 200,
      `the image shows the scene with its overlay (${px.nonBlack}/${px.total} lit, ${px.coloured} overlay-coloured pixels)`);
    await sleep(500); // let the last render and plots settle
    const shot = path.join(args.out, 'viewer_live.png');
    const bottom = await page.evaluate(() => Math.ceil(document.getElementById('plots').getBoundingClientRect().bottom));
    await page.screenshot({ path: shot, clip: { x: 0, y: 0, width: 1500, height: Math.min(1000, bottom) } });
    check(fs.statSync(shot).size > 20000, `screenshot saved: ${shot}`);
    console.log(`live: ${frames} frames, ${landmarks} landmarks; viewer ${JSON.stringify(viewerStats)}`);
  } finally {
    if (browser) await browser.context.close();
    if (browser) fs.rmSync(browser.userDataDir, { recursive: true, force: true });
    run.child.kill('SIGTERM');  // ends --view-hold
    const { code } = await Promise.race([run.exited, sleep(20000).then(() => ({ code: 'timeout' }))]);
    if (code === 'timeout') run.child.kill('SIGKILL');
    check(code === 0, `rtslam run --view exited cleanly on SIGTERM (${code})`);
  }
}

async function replayTest() {
  const dir = path.join(args.out, 'replay-run');
  fs.rmSync(dir, { recursive: true, force: true });
  let r = spawnSync(args.cli, ['run', '--duration', '3', '--seed', '1', '--out', dir, '--quiet'], { stdio: 'inherit' });
  check(r.status === 0, 'rtslam run wrote an output folder');
  r = spawnSync(args['live-run'], ['--duration', '3', '--seed', '1', '--overlays', path.join(dir, 'overlays')], { stdio: 'inherit' });
  check(r.status === 0, 'its overlays were written');
  const summary = JSON.parse(fs.readFileSync(path.join(dir, 'summary.json'), 'utf8'));
  const frames = summary.frames, landmarks = summary.landmarks.final;
  const overlays = fs.readdirSync(path.join(dir, 'overlays')).filter((f) => f.endsWith('.png')).length;
  check(overlays === frames, `one overlay PNG per processed frame (${overlays} for ${frames} frames)`);

  const view = start(args.cli, ['view', dir, '--addr', '127.0.0.1:0']);
  let browser;
  try {
    const urlLine = await until('the viewer URL', () => lineWith(view, 'viewer: '), 60000);
    const url = urlLine.slice('viewer: '.length).trim();
    browser = await launch();
    const { page } = browser;
    await page.goto(url);
    const p0 = await until('the replay to load', async () => {
      const p = await probe(page);
      return p.mode === 'replay' && p.historyLength === frames && p.landmarksShown > 0 && p.imagesShown >= 1 && p;
    }, 60000);
    check(p0.sceneReady, 'the 3D view loaded');
    check(p0.landmarksShown === landmarks, `the 3D view shows the run's ${landmarks} landmarks (shows ${p0.landmarksShown})`);
    check(Number(await page.textContent('#landmark-count')) === landmarks, 'the header shows the same number');
    check(p0.lastImageFrame === frames - 1, `the slider starts at the last frame (image of frame ${p0.lastImageFrame})`);
    // Move the slider: the image and the 3D view follow.
    const target = Math.floor(frames / 2);
    await page.evaluate((k) => {
      const s = document.getElementById('slider');
      s.value = String(k);
      s.dispatchEvent(new Event('input'));
    }, target);
    const p1 = await until('the image of the slider position', async () => {
      const p = await probe(page);
      return p.lastImageFrame === target && p;
    }, 30000);
    await sleep(300);
    const p2 = await probe(page);
    check(p1.imagesShown > p0.imagesShown, `the image follows the slider (frame ${target})`);
    check(p2.sceneRenders > p0.sceneRenders, `the 3D view follows the slider (${p0.sceneRenders} → ${p2.sceneRenders} renders)`);
    const label = await page.textContent('#slider-label');
    check(label.includes(`frame ${target}`), `the slider label names the frame (${label})`);
    const px = await overlayPixels(page);
    check(px.coloured > 100, `the replayed image shows its overlay (${px.coloured} overlay-coloured pixels)`);
    await sleep(500);
    const shot = path.join(args.out, 'viewer_replay.png');
    await page.screenshot({ path: shot, fullPage: true });
    check(fs.statSync(shot).size > 20000, `screenshot saved: ${shot}`);
  } finally {
    if (browser) await browser.context.close();
    if (browser) fs.rmSync(browser.userDataDir, { recursive: true, force: true });
    view.child.kill('SIGTERM');
    const { code } = await Promise.race([view.exited, sleep(20000).then(() => ({ code: 'timeout' }))]);
    if (code === 'timeout') view.child.kill('SIGKILL');
    check(code === 0, `rtslam view stopped cleanly on SIGTERM (${code})`);
  }
}

try {
  await (mode === 'live' ? liveTest() : replayTest());
  console.log(`${mode}: 1 passed, 0 failed`);
} catch (e) {
  if (!process.exitCode) console.error(`FAILED: ${e.stack || e}`);
  console.log(`${mode}: 0 passed, 1 failed`);
  process.exit(1);
}
