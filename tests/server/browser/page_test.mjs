// The web page in a real browser: Debian's headless Chromium, driven by puppeteer-core, against a
// moreau-server on 127.0.0.1 that requires a token.
//
// It loads the page (the API answers 401 until the token is entered), enters the token, submits the
// shipped manipulator scene with an override, waits for the job's row to say done, checks that the four
// figures loaded (natural width > 0) and the report is shown in words, reloads to check that the token
// was kept for the tab, then submits a scene whose name is HTML with a script and an error whose text is
// HTML, and checks that both are shown as text and nothing ran; cancels a long job and deletes it. It fails on any page error or CSP
// violation, and saves a screenshot.
//
// Usage: node page_test.mjs SERVER_BINARY SOURCE_DIR SCREENSHOT.png|.jpg
import puppeteer from 'puppeteer-core';
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import readline from 'node:readline';

const [serverBin, sourceDir, screenshotPath] = process.argv.slice(2);
if (!serverBin || !sourceDir || !screenshotPath) {
  console.error('usage: node page_test.mjs SERVER_BINARY SOURCE_DIR SCREENSHOT.png');
  process.exit(2);
}
const TOKEN = 'browser-test-token';
const XSS_NAME = '<img src=x onerror="window.__xss=1"><script>window.__xss=2</script>';
const WAIT = { timeout: 30000 };

function check(condition, message) {
  if (!condition) throw new Error('check failed: ' + message);
  console.log('ok:', message);
}

// The server, on a free port it picks and prints: wait for that line, not for a time.
async function startServer(dataDir) {
  const proc = spawn(serverBin, ['--host', '127.0.0.1', '--port', '0', '--token', TOKEN, '--workers', '2',
                                 '--data', dataDir, '--scenes', path.join(sourceDir, 'scenes')],
                     { stdio: ['ignore', 'pipe', 'inherit'] });
  const lines = readline.createInterface({ input: proc.stdout });
  const url = await new Promise((resolve, reject) => {
    lines.on('line', (line) => {
      const m = line.match(/listening on (http:\/\/127\.0\.0\.1:\d+)/);
      if (m) resolve(m[1]);
    });
    proc.on('exit', (code) => reject(new Error('moreau-server exited with ' + code + ' before listening')));
  });
  lines.on('line', () => {});  // keep draining
  return { proc, url };
}

async function stopServer(proc) {
  if (proc.exitCode !== null) return;
  const exited = new Promise((resolve) => proc.on('exit', resolve));
  proc.kill('SIGTERM');
  await exited;
}

async function main() {
  const dataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'moreau-browser-'));
  const { proc, url } = await startServer(path.join(dataDir, 'data'));
  let browser;
  try {
    browser = await puppeteer.launch({
      executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
      headless: true,
      args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage'],
    });
    const page = await browser.newPage();
    await page.setViewport({ width: 1280, height: 900 });
    const problems = [];
    page.on('pageerror', (e) => problems.push('page error: ' + e.message));
    // Failed loads are expected only where the test provokes them: 401s before the token is entered, the
    // 400 of the bad submission (POST /v1/jobs), and 404s for the job it deleted. Any other is a problem.
    let expected = { status: 401, url: '' };
    page.on('console', (m) => {
      if (m.type() !== 'error') return;
      const status = /Failed to load resource: the server responded with a status of (\d+)/.exec(m.text());
      const url = (m.location() && m.location().url) || '';
      if (status && expected && Number(status[1]) === expected.status && url.includes(expected.url)) return;
      problems.push('console error: ' + m.text() + (url ? ' (' + url + ')' : ''));
    });

    await page.goto(url + '/', { waitUntil: 'load' });
    await page.waitForFunction(() => document.getElementById('list-error').textContent.includes('401'), WAIT);
    check(true, 'without the token the page says the API needs one (401)');

    await page.type('#token', TOKEN);
    await page.click('#token-form button');
    await page.waitForFunction(() => document.getElementById('scene-select').value === 'manipulator', WAIT);
    expected = null;  // from here on, no failed load is expected
    check(true, 'with the token the shipped scenes are listed and manipulator is chosen');

    await page.type('#overrides', 'integrator.t_end=2');
    await page.click('#submit-button');
    await page.waitForFunction(() => [...document.querySelectorAll('#jobs tbody tr')].some(
      (tr) => tr.querySelector('td.scene').textContent === 'manipulator' && tr.querySelector('td.state').textContent === 'done'), WAIT);
    check(true, 'the submitted job reaches done in the list (live, from its event stream)');

    await page.waitForFunction(() => {
      const imgs = [...document.querySelectorAll('#job-figures img')];
      return imgs.length === 4 && imgs.every((i) => i.complete && i.naturalWidth > 0);
    }, WAIT);
    const widths = await page.$$eval('#job-figures img', (imgs) => imgs.map((i) => [i.dataset.kind, i.naturalWidth]));
    check(widths.length === 4 && widths.every(([, w]) => w === 1200), 'the four figures loaded at 1200 px: ' + JSON.stringify(widths));
    const summary = await page.$eval('#job-summary', (e) => e.textContent);
    check(summary.includes('completed') && summary.includes('2000 to t = 2'), 'the report is shown: ' + summary.slice(0, 120));
    const guarantees = await page.$$eval('#job-guarantees > li', (lis) => lis.map((li) => li.textContent));
    check(guarantees.some((g) => g.includes('Theorem 4.1')), 'the guarantees are listed (' + guarantees.length + ')');
    const downloads = await page.$$eval('#job-downloads a', (as) => as.map((a) => a.textContent));
    check(JSON.stringify(downloads) === JSON.stringify(['report.json', 'trajectory.csv', 'trajectory.json']), 'download links: ' + downloads);
    // PNG, or JPEG for a .jpg path (the one docs/ shows: docs/figures/web-page.jpg).
    const jpeg = screenshotPath.endsWith('.jpg');
    await page.screenshot({ path: screenshotPath, fullPage: true, type: jpeg ? 'jpeg' : 'png', ...(jpeg ? { quality: 60 } : {}) });
    check(fs.statSync(screenshotPath).size > 10000, 'screenshot saved to ' + screenshotPath);

    // The token is kept for the tab: after a reload the list loads without typing it again.
    await page.reload({ waitUntil: 'load' });
    await page.waitForFunction(() => document.querySelectorAll('#jobs tbody tr').length >= 1, WAIT);
    check(await page.$eval('#list-error', (e) => e.textContent === ''), 'after a reload the token is still used (session storage)');

    // A scene named with HTML and a script: shown as text, nothing runs.
    const scene = await page.evaluate(async (token) => {
      const r = await fetch('/v1/scenes/manipulator', { headers: { Authorization: 'Bearer ' + token } });
      return r.json();
    }, TOKEN);
    scene.name = XSS_NAME;
    scene.integrator.t_end = 0.2;
    await page.evaluate((text) => {
      document.querySelector('input[value=pasted]').checked = true;
      document.getElementById('scene-text').value = text;
      document.getElementById('overrides').value = '';
    }, JSON.stringify(scene));
    await page.click('#submit-button');
    await page.waitForFunction((name) => [...document.querySelectorAll('#jobs td.scene')].some((td) => td.textContent === name), WAIT, XSS_NAME);
    await page.waitForFunction(() => document.getElementById('job-summary').textContent.includes('completed'), WAIT);
    const ran = await page.evaluate(() => ({
      xss: window.__xss, scripts: document.querySelectorAll('script').length, injectedImg: document.querySelectorAll('img[src="x"]').length,
    }));
    // (The Content-Security-Policy would also stop an injected handler from running; the element counts
    // are what show that nothing was parsed as HTML.)
    // The page's own scripts: three.js, its OrbitControls, the 3D view and app.js.
    check(ran.xss === undefined && ran.scripts === 4 && ran.injectedImg === 0,
          'a scene named with HTML and a script is shown as text and nothing in it ran: ' + JSON.stringify(ran));

    // A scene named with a bidirectional override and control characters: shown as visible escapes
    // (a name shown as "ctl...live" was "ctl", U+202E, "...evil"), in the list and in the job's summary.
    scene.name = 'ctl\u202e...evil\u001b[2J\u2066';
    const shownName = 'ctl\\u{202e}...evil\\u{1b}[2J\\u{2066}';
    await page.evaluate((text) => {
      document.querySelector('input[value=pasted]').checked = true;
      document.getElementById('scene-text').value = text;
      document.getElementById('overrides').value = '';
    }, JSON.stringify(scene));
    await page.click('#submit-button');
    await page.waitForFunction((name) => [...document.querySelectorAll('#jobs td.scene')].some((td) => td.textContent === name), WAIT, shownName);
    await page.waitForFunction((name) => document.getElementById('job-summary').textContent.includes(name), WAIT, shownName);
    const bidi = await page.evaluate(() => /[\u202a-\u202e\u2066-\u2069\u0000-\u0008\u000b-\u001f\u007f-\u009f]/.test(document.body.textContent));
    check(!bidi, 'a scene named with a bidirectional override and control characters is shown with them as visible escapes');

    // An error whose text is HTML (an override path): shown as text.
    await page.evaluate(() => {
      document.querySelector('input[value=shipped]').checked = true;
      document.getElementById('overrides').value = '<b>bold</b>=1';
    });
    expected = { status: 400, url: '/v1/jobs' };
    await page.click('#submit-button');
    await page.waitForFunction(() => document.getElementById('submit-error').textContent.includes('400'), WAIT);
    const error = await page.$eval('#submit-error', (e) => ({ text: e.textContent, elements: e.children.length }));
    expected = null;
    check(error.text.includes("'<b>bold</b>'") && error.elements === 0 && (await page.$$('b')).length === 0,
          'an error message holding HTML is shown as text: ' + error.text);

    // Cancel a long job from its page, then delete it with its results.
    await page.evaluate(() => {
      document.querySelector('input[value=shipped]').checked = true;
      document.getElementById('overrides').value = 'integrator.t_end=5e4\noutput.every=10000';
    });
    await page.click('#submit-button');
    // The job's view is redrawn as its state changes: each button is found and clicked in one step in
    // the page, so a redraw between finding and clicking cannot detach it.
    const clickWhenThere = (id) =>
      page.waitForFunction((buttonId) => {
        const b = document.getElementById(buttonId);
        if (!b) return false;
        b.click();
        return true;
      }, WAIT, id);
    await page.waitForFunction(() => document.getElementById('job-summary').textContent.includes('state') &&
                               document.getElementById('cancel-button') !== null, WAIT);
    const longId = await page.$eval('#job-id', (e) => e.textContent);
    await clickWhenThere('cancel-button');
    await page.waitForFunction((id) => {
      const tr = document.querySelector(`#jobs tr[data-id="${id}"]`);
      return tr && tr.querySelector('td.state').textContent.startsWith('cancelled');
    }, WAIT, longId);
    check(true, 'the Cancel button cancels a running job: its row says cancelled');
    expected = { status: 404, url: '/v1/jobs/' + longId };
    await clickWhenThere('delete-button');
    await page.waitForFunction((id) => document.querySelector(`#jobs tr[data-id="${id}"]`) === null, WAIT, longId);
    const gone = await page.evaluate(async (id, token) => (await fetch('/v1/jobs/' + id, { headers: { Authorization: 'Bearer ' + token } })).status,
                                     longId, TOKEN);
    check(gone === 404, 'the Delete button deletes the finished job with its results (then 404): ' + gone);

    check(problems.length === 0, 'no page errors, console errors or CSP violations' + (problems.length ? ': ' + problems.join('; ') : ''));
  } finally {
    if (browser) await browser.close();
    await stopServer(proc);
    fs.rmSync(dataDir, { recursive: true, force: true });
  }
}

main().then(() => console.log('browser test passed'), (e) => {
  console.error(e.stack || String(e));
  process.exit(1);
});
