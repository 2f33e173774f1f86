// Measures what the viewer costs the filter: the median per-frame SLAM time (the pipeline's own FrameStats
// t_total, rendering excluded) of the same simulated run without the viewer, with the viewer and no browser, and
// with the viewer and headless Chromium showing it, interleaved over several repetitions. Not a ctest (timings
// are not tests, docs/testing.md): run it by hand, docs/viewer.md quotes it.
//
//   node tests/viz/view_cost.mjs --live-run build/tests/viz/viz_live_run --node-modules build/web/node_modules \
//        [--duration 20] [--reps 3]
import { spawn } from 'node:child_process';
import { createRequire } from 'node:module';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import readline from 'node:readline';

const args = { duration: '20', reps: '3' };
for (let i = 2; i < process.argv.length; i += 2) args[process.argv[i].replace(/^--/, '')] = process.argv[i + 1];
const require = createRequire(path.join(path.resolve(args['node-modules']), 'noop.js'));
const { chromium } = require('playwright-core');

function run(extra, onUrl) {
  return new Promise((resolve, reject) => {
    const child = spawn(args['live-run'], ['--duration', args.duration, '--seed', '1', ...extra], { stdio: ['ignore', 'pipe', 'ignore'] });
    let result = null;
    readline.createInterface({ input: child.stdout }).on('line', (l) => {
      if (l.startsWith('viewer: ') && onUrl) onUrl(l.slice(8).trim());
      if (l.startsWith('result: ')) result = Object.fromEntries(l.slice(8).split(' ').map((s) => s.split('=')));
    });
    child.on('exit', (code) => (code === 0 && result ? resolve(result) : reject(new Error(`exit ${code}`))));
  });
}

async function withBrowser() {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'rtslam-view-cost-'));
  const ctx = await chromium.launchPersistentContext(dir, {
    executablePath: '/usr/bin/chromium', headless: true, viewport: { width: 1500, height: 1000 },
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync',
      '--enable-unsafe-swiftshader', '--use-angle=swiftshader'],
  });
  const page = ctx.pages()[0] || (await ctx.newPage());
  const r = await run(['--view', '127.0.0.1:0', '--wait-client', '60'], (url) => page.goto(url));
  await ctx.close();
  fs.rmSync(dir, { recursive: true, force: true });
  return r;
}

const modes = {
  'no viewer': () => run([]),
  'viewer, no browser': () => run(['--view', '127.0.0.1:0']),
  'viewer + Chromium': withBrowser,
};
const out = Object.fromEntries(Object.keys(modes).map((k) => [k, []]));
for (let rep = 0; rep < Number(args.reps); ++rep) {
  for (const [name, fn] of Object.entries(modes)) {
    const r = await fn();
    out[name].push(r);
    console.log(`rep ${rep + 1} ${name}: median ${r.slam_median_ms} ms over ${r.frames} frames; push median ${r.push_median_us} us (max ${r.push_max_us}), make_report median ${r.make_report_median_us} us, dropped ${r.dropped}`);
  }
}
const med = (v) => { const s = [...v].sort((a, b) => a - b); return s[s.length >> 1]; };
const base = med(out['no viewer'].map((r) => Number(r.slam_median_ms)));
for (const [name, rs] of Object.entries(out)) {
  const m = med(rs.map((r) => Number(r.slam_median_ms)));
  console.log(`${name}: per-frame median ${m.toFixed(4)} ms (${((100 * (m - base)) / base).toFixed(1)} % vs no viewer), median over ${rs.length} runs`);
}
