// The web page in a real browser: Debian's headless Chromium, driven by puppeteer-core, against a
// moreau-server on 127.0.0.1 that requires a token.
//
// It loads the page (the API answers 401 until the token is entered), enters the token, submits the
// shipped manipulator scene with an override, waits for the job's row to say done, checks that the four
// figures loaded (natural width > 0) and the report is shown in words, reloads to check that the token
// was kept for the tab, then submits a scene whose name is HTML with a script and an error whose text is
// HTML, and checks that both are shown as text and nothing ran; cancels a long job (its state said once)
// and deletes it. Then: a long job's live plot grows while it runs, with the time left, and its figures
// replace the plot when it is done; a figure enlarges and Escape closes it, its SVG link fetches SVG;
// numbers show 6 digits and copy in full; a study and a campaign submitted from the form show their
// tables, summaries and figures; back and forward go between them; two jobs are compared in one plot
// with a legend naming them; deep links open items in a fresh tab, and an unknown id says "not found".
// Every wait is on the page's state, never a fixed time. It fails on any page error or CSP violation,
// and saves screenshots: SCREENSHOT (the whole page after the first job) and web-NAME beside it for the
// other states (live, figure, study, campaign, compare, not-found).
//
// Usage: node page_test.mjs SERVER_BINARY SOURCE_DIR SCREENSHOT.png|.jpg
import puppeteer from 'puppeteer-core';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { check, cleanUp, run, startServer as startServerWith } from './harness.mjs';

const [serverBin, sourceDir, screenshotPath] = process.argv.slice(2);
if (!serverBin || !sourceDir || !screenshotPath) {
  console.error('usage: node page_test.mjs SERVER_BINARY SOURCE_DIR SCREENSHOT.png');
  process.exit(2);
}
const TOKEN = 'browser-test-token';
const startServer = (dataDir) => startServerWith(serverBin, sourceDir, dataDir, TOKEN);
const XSS_NAME = '<img src=x onerror="window.__xss=1"><script>window.__xss=2</script>';
const WAIT = { timeout: 30000 };

// In the page: whether the shown item has `count` figures, all loaded.
function figuresLoadedInPage() {
  window.figuresLoaded = (count) => {
    const imgs = [...document.querySelectorAll('#job-figures img')];
    return imgs.length === count && imgs.every((i) => i.complete && i.naturalWidth > 0);
  };
}

// Chooses what the form submits: a run, a study or a campaign.
async function setMode(page, mode) {
  await page.click(`input[name=mode][value=${mode}]`);
}

// Screenshots of the page's states beside SCREENSHOT: web-live.jpg next to web-page.jpg (JPEG, or PNG
// for a .png path), the viewport only, to keep each small.
let shotBase = null;
async function shot(page, name, selector) {
  if (selector) await page.$eval(selector, (e) => e.scrollIntoView({ block: 'start', inline: 'nearest' }));
  const jpeg = shotBase.ext === '.jpg';
  const file = path.join(shotBase.dir, `web-${name}${shotBase.ext}`);
  await page.screenshot({ path: file, type: jpeg ? 'jpeg' : 'png', ...(jpeg ? { quality: 55 } : {}) });
  check(fs.statSync(file).size > 10000, 'screenshot saved to ' + file);
}

async function main() {
  shotBase = { dir: path.dirname(screenshotPath), ext: path.extname(screenshotPath) };
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
    await page.evaluateOnNewDocument(figuresLoadedInPage);
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
    // The whole page, at three quarters of its size to keep the file small.
    const size = await page.evaluate(() => ({ width: document.documentElement.scrollWidth, height: document.documentElement.scrollHeight }));
    await page.screenshot({ path: screenshotPath, clip: { x: 0, y: 0, ...size, scale: 0.75 }, captureBeyondViewport: true,
                            type: jpeg ? 'jpeg' : 'png', ...(jpeg ? { quality: 55 } : {}) });
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
    const shownBefore = await page.$eval('#job-id', (e) => e.textContent);
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
    // (The new job's view, not the one shown before it.)
    await page.waitForFunction((before) => document.getElementById('job-id').textContent !== before &&
                               document.getElementById('job-summary').textContent.includes('state') &&
                               document.getElementById('cancel-button') !== null, WAIT, shownBefore);
    const longId = await page.$eval('#job-id', (e) => e.textContent);
    await clickWhenThere('cancel-button');
    await page.waitForFunction((id) => {
      const tr = document.querySelector(`#jobs tr[data-id="${id}"]`);
      return tr && tr.querySelector('td.state').textContent.startsWith('cancelled');
    }, WAIT, longId);
    check(true, 'the Cancel button cancels a running job: its row says cancelled');
    const cancelledText = await page.$eval(`#jobs tr[data-id="${longId}"] td.state`, (td) => td.textContent);
    check(/^cancelled by request at step \d+$/.test(cancelledText), 'the cancelled state is said once: ' + cancelledText);
    expected = { status: 404, url: '/v1/jobs/' + longId };
    await clickWhenThere('delete-button');
    await page.waitForFunction((id) => document.querySelector(`#jobs tr[data-id="${id}"]`) === null, WAIT, longId);
    const gone = await page.evaluate(async (id, token) => (await fetch('/v1/jobs/' + id, { headers: { Authorization: 'Bearer ' + token } })).status,
                                     longId, TOKEN);
    check(gone === 404, 'the Delete button deletes the finished job with its results (then 404): ' + gone);

    // ---- A live plot while a job runs, then its figures --------------------------------------------
    // A 7-joint arm tracking a trajectory for 60 s of simulated time at h = 1e-5 (6 million steps:
    // seconds of work): the page draws q(t) from the job's `sample` events as they come.
    await setMode(page, 'run');
    await page.evaluate(() => {
      document.querySelector('input[value=shipped]').checked = true;
      document.getElementById('scene-select').value = 'iiwa14-tracking';
      document.getElementById('overrides').value = 'integrator.t_end=60\nintegrator.h=1e-5\noutput.every=1000';
    });
    await page.click('#submit-button');
    await page.waitForFunction(() => /^#\/jobs\/[0-9a-f]{32}$/.test(location.hash) && document.getElementById('job-id').textContent === location.hash.slice(7), WAIT);
    const liveId = await page.$eval('#job-id', (e) => e.textContent);
    await page.waitForFunction(() => {
      const svg = document.getElementById('live-svg');
      return svg && Number(svg.dataset.points) >= 2 && !document.getElementById('live-section').hidden;
    }, WAIT);
    const firstPoints = await page.$eval('#live-svg', (svg) => Number(svg.dataset.points));
    await page.waitForFunction((n) => {
      const svg = document.getElementById('live-svg');
      return svg && Number(svg.dataset.points) > n && !document.getElementById('live-section').hidden;
    }, WAIT, firstPoints);
    const live = await page.evaluate(() => ({
      points: Number(document.getElementById('live-svg').dataset.points),
      lines: document.querySelectorAll('#live-svg polyline.series').length,
      legend: [...document.querySelectorAll('#live-plot ul.legend li')].map((li) => li.textContent),
      state: document.querySelector(`#jobs tr[data-id="${document.getElementById('job-id').textContent}"] td.state`).textContent,
    }));
    check(live.points > firstPoints && live.lines === 7 && live.state === 'running',
          `the live plot grows while the job runs: ${firstPoints} then ${live.points} states, 7 coordinates drawn (${live.state})`);
    check(live.legend.length === 7 && live.legend.every((name, i) => name === `iiwa_joint_${i + 1}`),
          'the live plot names the coordinates as the scene does: ' + live.legend.join(', '));
    await page.waitForFunction(() => / left$/.test(document.getElementById('job-progress').textContent), WAIT);
    check(true, 'the running job shows its progress with the time left: ' + await page.$eval('#job-progress', (e) => e.textContent));
    // The screenshot with a few seconds drawn (unless the run is over by then: then as it was).
    await page.waitForFunction(() => document.getElementById('live-section').hidden ||
                               Number(document.getElementById('live-svg').dataset.points) >= 30, { timeout: 120000 });
    await shot(page, 'live', '#job-section');
    await page.waitForFunction(() => document.getElementById('live-section').hidden && figuresLoaded(4), { timeout: 120000 });
    check(true, 'when the job is done its four figures replace the live plot');

    // ---- Figures: enlarge (Escape closes), PNG and SVG downloads ------------------------------------
    await page.click('#job-figures img[data-kind=state]');
    await page.waitForFunction(() => document.getElementById('figure-dialog').open &&
                               document.getElementById('figure-large').naturalWidth === 1200, WAIT);
    await shot(page, 'figure');
    await page.keyboard.press('Escape');
    await page.waitForFunction(() => !document.getElementById('figure-dialog').open, WAIT);
    check(true, 'a figure clicked opens large in a dialog, and Escape closes it');
    const formats = await page.$$eval('#job-figures figcaption a.figure-download', (as) => as.map((a) => a.dataset.format + ':' + a.textContent));
    check(formats.length === 8 && formats.filter((f) => f === 'svg:SVG').length === 4, 'each figure has PNG and SVG links: ' + formats.length);
    const svgResponse = page.waitForResponse((r) => r.url().includes(`/v1/jobs/${liveId}/figure?kind=phase&format=svg`) && r.status() === 200, WAIT);
    await page.click('#job-figures figure:nth-child(4) a[data-format=svg]');
    const svgType = (await svgResponse).headers()['content-type'];
    check(svgType.startsWith('image/svg+xml'), 'the SVG link fetches the figure as SVG: ' + svgType);

    // ---- Numbers: 6 significant digits shown, the full value on hover and on copy ---------------------
    const numbers = await page.$$eval('#job-summary dd .num[data-full]', (spans) => spans.map((s) => [s.textContent, s.title, s.dataset.full]));
    check(numbers.length > 0 && numbers.every(([shown, title, full]) => title === full && Number(shown) === Number(Number(full).toPrecision(6)) &&
                                               shown.replace(/^-?0\.0*|[-.]|e.*$/g, '').length <= 6),
          'numbers are shown to 6 significant digits with the full value as their title: ' + JSON.stringify(numbers[0]));
    const copied = await page.evaluate(() => {
      const dd = [...document.querySelectorAll('#job-summary dt')].find((dt) => dt.textContent === 'final state').nextElementSibling;
      const range = document.createRange();
      range.selectNodeContents(dd);
      document.getSelection().removeAllRanges();
      document.getSelection().addRange(range);
      const data = new DataTransfer();
      document.dispatchEvent(new ClipboardEvent('copy', { clipboardData: data, bubbles: true, cancelable: true }));
      document.getSelection().removeAllRanges();
      return { shown: dd.textContent, copied: data.getData('text/plain'), full: [...dd.querySelectorAll('[data-full]')].map((s) => s.dataset.full) };
    });
    check(copied.full.length > 0 && copied.full.every((f) => copied.copied.includes(f)) && copied.copied.length > copied.shown.length,
          'copying the final state copies the full values: ' + copied.copied.slice(0, 80));
    const plain = await page.evaluate(async (id, token) => {
      const report = await (await fetch(`/v1/jobs/${id}/report`, { headers: { Authorization: 'Bearer ' + token } })).json();
      return { summary: report.summary, shown: document.getElementById('job-plain').textContent };
    }, liveId, TOKEN);
    check(typeof plain.summary === 'string' && plain.summary.length > 20 && plain.shown === plain.summary,
          'the report\'s plain-language summary is shown above the guarantees: ' + JSON.stringify(plain));

    // ---- A study: step sizes and schemes, its table and figures ---------------------------------------
    await setMode(page, 'study');
    await page.evaluate(() => {
      document.querySelector('input[value=shipped]').checked = true;
      document.getElementById('scene-select').value = 'manipulator';
      document.getElementById('overrides').value = 'integrator.t_end=1';
      document.getElementById('study-h').value = '1e-2:1e-3:2';
      for (const box of document.querySelectorAll('#study-schemes input')) box.checked = box.value !== 'regularized';
    });
    await page.click('#submit-button');
    await page.waitForFunction(() => /^#\/studies\/[0-9a-f]{32}$/.test(location.hash), WAIT);
    await page.waitForFunction(() => {
      const t = document.querySelector('#job-table table.results');
      return t && t.tBodies[0].rows.length === 4 && figuresLoaded(2);
    }, { timeout: 120000 });
    const study = await page.evaluate(() => ({
      id: document.getElementById('job-id').textContent,
      title: document.getElementById('job-title').textContent,
      schemes: [...document.querySelectorAll('#job-table table.results')[0].tBodies[0].rows].map((tr) => tr.cells[0].textContent),
      downloads: [...document.querySelectorAll('#job-downloads a')].map((a) => a.textContent),
      row: document.querySelector(`#jobs tr[data-id="${document.getElementById('job-id').textContent}"] td.kind`).textContent,
    }));
    check(study.title === 'Study' && JSON.stringify(study.schemes.sort()) === JSON.stringify(['abl', 'abl', 'explicit', 'explicit']) &&
          study.downloads.includes('table.csv') && study.row === 'study',
          'a study submitted from the page shows its table (2 schemes x 2 step sizes), its two figures and downloads, and is listed: ' + JSON.stringify(study));
    await shot(page, 'study', '#job-section');

    // ---- A campaign: two inputs with ranges and a sample count, its summary and figures ---------------
    await setMode(page, 'campaign');
    await page.evaluate(() => {
      document.querySelector('input[value=shipped]').checked = true;
      document.getElementById('scene-select').value = 'manipulator';
      document.getElementById('overrides').value = 'integrator.t_end=3';
      document.getElementById('campaign-inputs').replaceChildren();
      document.getElementById('add-input').click();
      document.getElementById('add-input').click();
      const rows = document.querySelectorAll('#campaign-inputs .input-row');
      const set = (row, path, low, high) => {
        row.querySelector('.input-path').value = path;
        row.querySelector('.input-low').value = low;
        row.querySelector('.input-high').value = high;
      };
      set(rows[0], '/parameters/m1', '0.8', '1.2');
      set(rows[1], '/initial/q/0', '2', '4');
      document.getElementById('campaign-samples').value = '8';
      document.getElementById('campaign-sampler').value = 'sobol';
    });
    await page.click('#submit-button');
    await page.waitForFunction(() => /^#\/campaigns\/[0-9a-f]{32}$/.test(location.hash), WAIT);
    await page.waitForFunction(() => document.getElementById('campaign-text') && document.getElementById('campaign-text').textContent.length > 0 &&
                               figuresLoaded(3), { timeout: 120000 });
    const campaign = await page.evaluate(() => ({
      id: document.getElementById('job-id').textContent,
      title: document.getElementById('job-title').textContent,
      summary: document.getElementById('job-summary').textContent,
      downloads: [...document.querySelectorAll('#job-downloads a')].map((a) => a.textContent),
    }));
    check(campaign.title === 'Campaign' && campaign.summary.includes('8 of 8') && campaign.downloads.includes('samples.csv'),
          'a campaign submitted from the page shows its summary, its three figures and downloads: ' + JSON.stringify(campaign.downloads));
    await shot(page, 'campaign', '#job-section');

    // ---- Back and forward between the items chosen -----------------------------------------------------
    await page.goBack();
    await page.waitForFunction((id) => document.getElementById('job-id').textContent === id && location.hash === '#/studies/' + id, WAIT, study.id);
    await page.goBack();
    await page.waitForFunction((id) => document.getElementById('job-id').textContent === id && location.hash === '#/jobs/' + id, WAIT, liveId);
    await page.goForward();
    await page.waitForFunction((id) => document.getElementById('job-id').textContent === id && document.getElementById('job-title').textContent === 'Study', WAIT, study.id);
    check(true, 'back and forward go between the job, the study and the campaign chosen');
    // Clicked in the page in one go: the list redraws a row's cells at every update of its item, so a
    // handle taken before the click may be gone by the time it lands ("Node is detached").
    await page.evaluate((id) => document.querySelector(`#jobs tr[data-id="${id}"] td.scene`).click(), campaign.id);
    await page.waitForFunction((id) => location.hash === '#/campaigns/' + id && document.getElementById('job-id').textContent === id, WAIT, campaign.id);
    check(true, 'choosing a row in the list sets the address to it');

    // ---- Compare two runs: an implicit and an explicit tracking controller -----------------------------
    await setMode(page, 'run');
    const compareIds = [];
    for (const name of ['manipulator-tracking', 'manipulator-tracking-explicit']) {
      await page.evaluate((scene) => {
        document.querySelector('input[value=shipped]').checked = true;
        document.getElementById('scene-select').value = scene;
        document.getElementById('overrides').value = 'integrator.t_end=3';
      }, name);
      await page.click('#submit-button');
      await page.waitForFunction((prev) => /^#\/jobs\/[0-9a-f]{32}$/.test(location.hash) && !prev.includes(location.hash.slice(7)), WAIT, compareIds);
      compareIds.push(await page.evaluate(() => location.hash.slice(7)));
    }
    for (const id of compareIds) {
      // Ticked in the page once it can be (the job has its trajectory), in one go for the same reason.
      await page.waitForFunction((jobId) => {
        const box = document.querySelector(`#jobs tr[data-id="${jobId}"] td.pick input`);
        if (!box || box.disabled) return false;
        if (!box.checked) box.click();
        return box.checked;
      }, { timeout: 60000 }, id);
    }
    await page.waitForFunction(() => !document.getElementById('compare-button').disabled, WAIT);
    await page.click('#compare-button');
    await page.waitForFunction(() => new Set([...document.querySelectorAll('#compare-svg polyline.series')].map((p) => p.dataset.series)).size === 2, WAIT);
    // Another quantity: a velocity (the columns the trajectories share are offered).
    const velocity = await page.$$eval('#compare-quantity option', (os) => os.map((o) => o.value).find((v) => v.endsWith('_dot')));
    await page.select('#compare-quantity', velocity);
    await page.waitForFunction((v) => document.querySelector('#compare-svg text:last-of-type') &&
                               [...document.querySelectorAll('#compare-svg text')].some((t) => t.textContent === v) &&
                               new Set([...document.querySelectorAll('#compare-svg polyline.series')].map((p) => p.dataset.series)).size === 2, WAIT, velocity);
    const legend = await page.$$eval('#compare-plot ul.legend li', (lis) => lis.map((li) => li.textContent));
    check(legend.length === 2 && legend.some((l) => l.startsWith('manipulator-tracking, tracking, h = 0.001')) &&
          legend.some((l) => l.startsWith('manipulator-tracking-explicit, tracking, h = 0.001')),
          'two jobs compared: two series drawn in one plot, the legend names each (scene, scheme, h): ' + JSON.stringify(legend));
    await shot(page, 'compare', '#compare-section');

    // ---- A deep link in a fresh tab (which needs the token again), and an unknown id -------------------
    const fresh = await browser.newPage();
    await fresh.evaluateOnNewDocument(figuresLoadedInPage);
    await fresh.setViewport({ width: 1280, height: 900 });
    let freshExpected = 401;
    fresh.on('pageerror', (e) => problems.push('fresh tab page error: ' + e.message));
    fresh.on('console', (m) => {
      if (m.type() !== 'error') return;
      const status = /Failed to load resource: the server responded with a status of (\d+)/.exec(m.text());
      if (status && Number(status[1]) === freshExpected) return;
      problems.push('fresh tab console error: ' + m.text());
    });
    await fresh.goto(`${url}/#/studies/${study.id}`, { waitUntil: 'load' });
    await fresh.waitForFunction(() => document.getElementById('list-error').textContent.includes('401'), WAIT);
    await fresh.type('#token', TOKEN);
    await fresh.click('#token-form button');
    await fresh.waitForFunction((id) => document.getElementById('job-id').textContent === id &&
                                document.querySelectorAll('#job-table table.results').length === 2, WAIT, study.id);
    freshExpected = 404;
    check(true, 'a deep link to the study opens it in a fresh tab');
    await fresh.goto(`${url}/#/jobs/${liveId}`, { waitUntil: 'load' });
    await fresh.waitForFunction((id) => document.getElementById('job-id').textContent === id && figuresLoaded(4), WAIT, liveId);
    check(true, 'a deep link to the job opens it with its figures');
    const missing = '0123456789abcdef0123456789abcdef';
    await fresh.goto(`${url}/#/campaigns/${missing}`, { waitUntil: 'load' });
    await fresh.waitForFunction(() => !document.getElementById('job-notfound').hidden, WAIT);
    const notFound = await fresh.evaluate(() => ({ text: document.getElementById('job-notfound').textContent, details: document.getElementById('job-details').hidden }));
    check(notFound.text.startsWith('Not found') && notFound.text.includes(missing) && notFound.details,
          'an unknown id says it is not found: ' + notFound.text);
    await shot(fresh, 'not-found');
    await fresh.close();

    check(problems.length === 0, 'no page errors, console errors or CSP violations' + (problems.length ? ': ' + problems.join('; ') : ''));
  } finally {
    await cleanUp(browser, proc, dataDir);
  }
}

run(main);
