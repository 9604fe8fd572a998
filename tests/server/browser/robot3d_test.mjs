// The 3D view of a URDF robot (server/web/robot3d.js) in a real browser: Debian's headless Chromium
// (WebGL by SwiftShader, on the CPU), driven by puppeteer-core, against a moreau-server on 127.0.0.1 that
// requires a token.
//
// It submits the shipped KUKA iiwa (iiwa14-joint-limit) from the page for long enough to be running when
// its 3D view is opened, and checks that the view follows it: frames arrive while it runs, and once it is
// done the view holds the whole trajectory. Then it moves the time slider to several places and checks
// that the pose three.js holds for every link after the render (its matrixWorld) equals the server's
// forward kinematics at that time (GET /v1/jobs/{id}/kinematics?t=, fetched apart from the page). The
// same for a pendulum whose URDF has a box, a cylinder and a sphere, drawn with them.
// The tolerance: three.js r111 keeps a matrix as an Array of JavaScript numbers (doubles), and the page
// copies the server's numbers into the link's matrix under a scene whose own matrix is the identity, so
// the two agree to the last bit but for the sign of a zero; 1e-12 leaves room for that and for nothing a
// wrong pose could hide behind. (What reaches the GPU is float32, 6e-8 relative: drawn pixels are not
// compared, the poses are.) It fails on any page error, console error or CSP violation, and saves a
// screenshot of the view.
//
// Usage: node robot3d_test.mjs SERVER_BINARY SOURCE_DIR SCREENSHOT.png|.jpg
import puppeteer from 'puppeteer-core';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { check, cleanUp, run, startServer as startServerWith } from './harness.mjs';

const [serverBin, sourceDir, screenshotPath] = process.argv.slice(2);
if (!serverBin || !sourceDir || !screenshotPath) {
  console.error('usage: node robot3d_test.mjs SERVER_BINARY SOURCE_DIR SCREENSHOT.png');
  process.exit(2);
}
const TOKEN = 'browser-test-token';
const startServer = (dataDir) => startServerWith(serverBin, sourceDir, dataDir, TOKEN);
const WAIT = { timeout: 60000 };
const TOLERANCE = 1e-12;

// Moves the view's slider to `index`, then holds the world matrix three.js has for every link to the pose
// the server answers for the time the view shows. Returns the number of links compared.
async function compareAtSlider(page, api, id, index) {
  await page.evaluate((i) => {
    const s = document.querySelector('.robot3d-controls input[type=range]');
    s.value = String(i);
    s.dispatchEvent(new Event('input', { bubbles: true }));
  }, index);
  const drawn = await page.evaluate(() => window.MoreauRobot3D.drawnPoses());
  const shownText = await page.$eval('.robot3d-time', (e) => e.textContent);
  const server = await api(`/v1/jobs/${id}/kinematics?t=${drawn.t}`);
  check(server.frames.length === 1 && server.frames[0].row === drawn.row && server.frames[0].t === drawn.t,
        `slider at ${index}: the view shows row ${drawn.row} (${shownText}), the row the server has for t = ${drawn.t}`);
  const poses = server.frames[0].poses;
  check(drawn.links.length === server.links.length && drawn.links.every((l, k) => l.name === server.links[k].name),
        `the view draws the server's ${server.links.length} links`);
  let worst = 0;
  drawn.links.forEach((l, k) => {
    const p = poses[k];  // row-major [R | p]; three.js's elements are column-major
    for (let r = 0; r < 3; ++r) {
      for (let c = 0; c < 4; ++c) worst = Math.max(worst, Math.abs(l.matrix[4 * c + r] - p[4 * r + c]));
      worst = Math.max(worst, Math.abs(l.matrix[4 * r + 3]));  // the bottom row: 0 0 0
    }
    worst = Math.max(worst, Math.abs(l.matrix[15] - 1));
  });
  check(worst <= TOLERANCE, `at t = ${drawn.t} every link's drawn world matrix equals the server's pose (largest difference ${worst})`);
  return drawn.links.length;
}

async function main() {
  const dataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'moreau-robot3d-'));
  const { proc, url } = await startServer(path.join(dataDir, 'data'));
  const api = async (p) => {
    const r = await fetch(url + p, { headers: { Authorization: 'Bearer ' + TOKEN } });
    if (!r.ok) throw new Error(`GET ${p}: ${r.status} ${await r.text()}`);
    return r.json();
  };
  let browser;
  try {
    browser = await puppeteer.launch({
      executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
      headless: true,
      // WebGL without a GPU: SwiftShader, Chromium's software renderer.
      args: ['--no-sandbox', '--disable-dev-shm-usage', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
    });
    const page = await browser.newPage();
    await page.setViewport({ width: 1100, height: 1000 });
    const problems = [];
    page.on('pageerror', (e) => problems.push('page error: ' + e.message));
    page.on('console', (m) => {
      if (m.type() === 'error') problems.push('console error: ' + m.text());
    });

    await page.evaluateOnNewDocument((token) => sessionStorage.setItem('moreau-token', token), TOKEN);
    await page.goto(url + '/', { waitUntil: 'load' });
    check(await page.evaluate(() => typeof window.THREE === 'object' && window.THREE.REVISION === '111' &&
                              typeof window.THREE.OrbitControls === 'function' && typeof window.MoreauRobot3D === 'object'),
          'three.js r111, its OrbitControls and the 3D view are served by the server itself');
    await page.waitForFunction(() => [...document.querySelectorAll('#scene-select option')].some((o) => o.value === 'iiwa14-joint-limit'), WAIT);

    // The iiwa for 300 s of simulated time, a row every 20 steps: a few seconds of running, so that the
    // view opens on a running job and follows it.
    await page.evaluate(() => {
      document.getElementById('scene-select').value = 'iiwa14-joint-limit';
      document.getElementById('overrides').value = 'integrator.t_end=300\noutput.every=20';
    });
    await page.click('#submit-button');
    await page.waitForFunction(() => document.getElementById('robot3d-button') !== null, WAIT);
    const id = await page.$eval('#job-id', (e) => e.textContent);
    await page.evaluate(() => document.getElementById('robot3d-button').click());
    await page.waitForFunction(() => document.querySelector('.robot3d-canvas canvas') !== null, WAIT);
    // Following: what the view holds while the job runs, then once it is done.
    const seen = [];
    const deadline = Date.now() + 120000;
    for (;;) {
      const d = await page.evaluate(() => window.MoreauRobot3D.drawnPoses());
      if (d) seen.push({ final: d.final, t: d.t, frames: d.frames });
      if (d && d.final) break;
      if (Date.now() > deadline) throw new Error('the view did not reach the final state: ' + JSON.stringify(seen.slice(-3)));
      await new Promise((r) => setTimeout(r, 200));
    }
    const running = seen.filter((s) => !s.final);
    check(running.length > 0 && running.some((s) => s.t > 0 && s.t < 300),
          'the view followed the running job: it showed rows up to t = ' + running.map((s) => s.t).join(', ') + ' before the end');
    const job = await api('/v1/jobs/' + id);
    check(job.state === 'done', 'the job is done');
    const last = seen[seen.length - 1];
    check(last.t === 300 && last.frames === 400, 'once done the view shows the whole run: 400 frames up to t = ' + last.t);

    // The slider: the poses drawn at several times equal the server's forward kinematics there.
    const n = last.frames;
    let compared = 0;
    for (const index of [0, 37, Math.floor(n / 2), n - 2, n - 1]) compared += await compareAtSlider(page, api, id, index);
    check(compared === 5 * 10, 'compared ' + compared + ' link poses');
    // The arm moved between the first and the last frame (the comparison is not of a robot at rest).
    const first = await api(`/v1/jobs/${id}/kinematics?t=0`);
    const end = await api(`/v1/jobs/${id}/kinematics?t=300`);
    const tip = (k) => k.frames[0].poses[k.links.length - 1];
    check(Math.hypot(tip(first)[3] - tip(end)[3], tip(first)[7] - tip(end)[7], tip(first)[11] - tip(end)[11]) > 0.01,
          'the end effector moved between t = 0 and the end');

    // Play runs through the frames, Pause stops.
    await page.evaluate(() => {
      const s = document.querySelector('.robot3d-controls input[type=range]');
      s.value = '0';
      s.dispatchEvent(new Event('input', { bubbles: true }));
      document.querySelector('.robot3d-controls button').click();
    });
    await page.waitForFunction(() => window.MoreauRobot3D.drawnPoses().t > 1, WAIT);
    await page.evaluate(() => document.querySelector('.robot3d-controls button').click());
    check(true, 'Play moves the view through the frames; Pause stops it');

    // The screenshot: the view at t of about 1 s (the arm falling onto its joint limit).
    await page.evaluate(() => {
      const s = document.querySelector('.robot3d-controls input[type=range]');
      s.value = '3';
      s.dispatchEvent(new Event('input', { bubbles: true }));
    });
    const box = await page.$('#job-robot3d');
    const jpeg = screenshotPath.endsWith('.jpg');
    await box.screenshot({ path: screenshotPath, type: jpeg ? 'jpeg' : 'png', ...(jpeg ? { quality: 70 } : {}) });
    check(fs.statSync(screenshotPath).size > 10000, 'screenshot saved to ' + screenshotPath);

    // A robot drawn with its URDF's primitives (tests/server/shapes-pendulum.json): a box, a cylinder, and
    // a sphere on a link merged through a fixed joint; the mesh beside it is not drawn.
    const shapesScene = JSON.parse(fs.readFileSync(path.join(sourceDir, 'tests/server/shapes-pendulum.json'), 'utf8'));
    const submitted = await fetch(url + '/v1/jobs', {
      method: 'POST', headers: { Authorization: 'Bearer ' + TOKEN, 'Content-Type': 'application/json' },
      body: JSON.stringify({ scene: shapesScene }),
    });
    const shapesId = (await submitted.json()).id;
    await api(`/v1/jobs/${shapesId}?wait=30`);
    await page.waitForFunction((jid) => document.querySelector(`#jobs tr[data-id="${jid}"]`) !== null, WAIT, shapesId);
    await page.evaluate((jid) => document.querySelector(`#jobs tr[data-id="${jid}"]`).click(), shapesId);
    await page.waitForFunction((jid) => document.getElementById('job-id').textContent === jid &&
                               document.getElementById('robot3d-button') !== null, WAIT, shapesId);
    check(await page.evaluate(() => document.querySelector('.robot3d') === null), 'choosing another job closes the 3D view');
    await page.evaluate(() => document.getElementById('robot3d-button').click());
    await page.waitForFunction(() => { const d = window.MoreauRobot3D.drawnPoses(); return d && d.final; }, WAIT);
    const shapes = await page.evaluate(() => window.MoreauRobot3D.drawnPoses().links.map((l) => [l.name, l.shapes.join(' ')]));
    check(JSON.stringify(shapes) === JSON.stringify([['base', 'box'], ['arm', 'cylinder'], ['tip', 'sphere']]),
          'the pendulum is drawn with its URDF primitives: ' + JSON.stringify(shapes));
    const shapeFrames = (await page.evaluate(() => window.MoreauRobot3D.drawnPoses())).frames;
    for (const index of [0, Math.floor(shapeFrames / 3), shapeFrames - 1]) await compareAtSlider(page, api, shapesId, index);

    check(problems.length === 0, 'no page errors, console errors or CSP violations' + (problems.length ? ': ' + problems.join('; ') : ''));
  } finally {
    await cleanUp(browser, proc, dataDir);
  }
}

run(main);
