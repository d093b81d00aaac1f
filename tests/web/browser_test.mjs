// The device's web page in a real browser (Debian's chromium driven by puppeteer-core;
// nothing downloads a browser) against mirrorscand on the virtual board on loopback:
// the posture drawing before a scan; a wrong token is refused; log in; start a scan and
// see the progress reach 100 %; see the scan listed; download it byte-identical to the
// stored archive; the live preview; after `mirrorscan process --upload` the pose check's
// advice, the previews, the measurements and a non-blank 3D view; delete it. Screenshots
// go to MIRRORSCAN_ARTIFACTS (look at them).
//
// Run by ctest (tests/CMakeLists.txt sets the environment): node browser_test.mjs
import { spawn, spawnSync } from 'node:child_process';
import { createRequire } from 'node:module';
import { createHash } from 'node:crypto';
import fs from 'node:fs';
import net from 'node:net';
import os from 'node:os';
import path from 'node:path';

const env = (name) => {
  const value = process.env[name];
  if (!value) throw new Error(`${name} is not set (run through ctest)`);
  return value;
};
const BIN = env('MIRRORSCAN_BIN_DIR');
const SOURCE = env('MIRRORSCAN_SOURCE_DIR');
const WEB = env('MIRRORSCAN_WEB_DIR');
const ARTIFACTS = env('MIRRORSCAN_ARTIFACTS');
const CHROMIUM = process.env.MIRRORSCAN_CHROMIUM || '/usr/bin/chromium';
const require = createRequire(path.join(env('MIRRORSCAN_NODE_MODULES'), 'noop.js'));
const puppeteer = require('puppeteer-core');

const board = JSON.parse(fs.readFileSync(path.join(SOURCE, 'boards/virtual/board.json'), 'utf8'));
const TOKEN = board.service.token;
let failures = 0;
function check(condition, what) {
  console.log(`${condition ? 'ok  ' : 'FAIL'} ${what}`);
  if (!condition) failures += 1;
}
function sha256(file) {
  return createHash('sha256').update(fs.readFileSync(file)).digest('hex');
}
async function freePort() {
  return new Promise((resolve) => {
    const server = net.createServer();
    server.listen(0, '127.0.0.1', () => {
      const { port } = server.address();
      server.close(() => resolve(port));
    });
  });
}
function mirrorscan(args, extraEnv = {}) {
  const result = spawnSync(path.join(BIN, 'mirrorscan'), args, {
    env: { ...process.env, MIRRORSCAN_TOKEN: TOKEN, ...extraEnv }, encoding: 'utf8',
    maxBuffer: 64 << 20,
  });
  return result;
}
async function until(what, predicate, timeoutMs) {
  const deadline = Date.now() + timeoutMs;
  for (;;) {
    const value = await predicate();
    if (value) return value;
    if (Date.now() > deadline) throw new Error(`timed out waiting for ${what}`);
    await new Promise((r) => setTimeout(r, 200));
  }
}

const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'web_browser_test.'));
fs.mkdirSync(ARTIFACTS, { recursive: true });
const downloads = path.join(dir, 'downloads');
fs.mkdirSync(downloads);
// The mannequin turned 25° to its left (counter-clockwise seen from above): a scan the pose
// check flags, so the page shows its advice.
board.virtual.scene = path.join(dir, 'mannequin-turned.json');
fs.writeFileSync(board.virtual.scene, JSON.stringify({
  subject: { type: 'mannequin', yaw_deg: 25 }, frames: 300, seed: 1,
}));
fs.writeFileSync(path.join(dir, 'board.json'), JSON.stringify(board, null, 2));
const port = await freePort();
const host = `127.0.0.1:${port}`;
const daemonLog = fs.openSync(path.join(dir, 'daemon.log'), 'w');
const daemon = spawn(path.join(BIN, 'mirrorscand'), [
  '--board', path.join(dir, 'board.json'), '--data-dir', path.join(dir, 'data'),
  '--listen', host, '--web-dir', WEB,
], { stdio: ['ignore', daemonLog, daemonLog] });
let browser = null;

async function main() {
  await until('mirrorscand', async () => {
    try { return (await fetch(`http://${host}/api/v1/status`)).ok; } catch (e) { return false; }
  }, 30000);
  // The scene's true calibration on the device, so the scan names the one we process with.
  const truth = path.join(dir, 'truth');
  let r = mirrorscan(['sim', 'render', '--scene', board.virtual.scene, '--out', truth]);
  if (r.status !== 0) throw new Error(`sim render: ${r.stderr}`);
  r = mirrorscan(['device', 'calibration', 'put', path.join(truth, 'calibration.json'), '--host', host]);
  if (r.status !== 0) throw new Error(`calibration put: ${r.stderr}`);

  browser = await puppeteer.launch({
    executablePath: CHROMIUM,
    headless: true,
    // Root in a container: no sandbox. WebGL on SwiftShader (no GPU here).
    args: ['--no-sandbox', '--enable-unsafe-swiftshader', '--use-angle=swiftshader',
           '--window-size=1280,1400'],
    defaultViewport: { width: 1280, height: 1400 },
  });
  const page = await browser.newPage();
  const requests = [];
  page.on('request', (request) => requests.push(request.url()));
  page.on('dialog', (dialog) => dialog.accept());
  page.on('pageerror', (error) => check(false, `no script error on the page (${error.message})`));
  const cdp = await page.createCDPSession();
  await cdp.send('Browser.setDownloadBehavior', { behavior: 'allow', downloadPath: downloads });
  await page.goto(`http://${host}/`, { waitUntil: 'networkidle0' });
  await page.waitForFunction(() => document.getElementById('state').textContent === 'idle');
  check(true, 'the page shows the device idle');
  check(await page.$eval('#board', (e) => e.textContent) === 'board virtual', 'the page names the board');

  // Before any scan: the standard posture as a drawing (docs/scanning-posture.md).
  const drawing = await page.$eval('#posture-drawing', (svg) => {
    const box = svg.getBoundingClientRect();
    const armAngles = [...svg.querySelectorAll('line.arm')].map((l) => {
      const dx = l.x2.baseVal.value - l.x1.baseVal.value;
      const dy = l.y2.baseVal.value - l.y1.baseVal.value;
      return Math.atan2(Math.abs(dx), dy) * 180 / Math.PI;  // from hanging straight down
    });
    const feet = [...svg.querySelectorAll('ellipse.footprint')].map((e) => e.cx.baseVal.value);
    const legs = [...svg.querySelectorAll('line.leg')].map((l) => l.x2.baseVal.value);
    const level = svg.querySelector('line.head-level');
    return {
      width: box.width, height: box.height, armAngles, feet, legs,
      fists: svg.querySelectorAll('circle.fist').length,
      headLevel: level && level.y1.baseVal.value === level.y2.baseVal.value,
      steps: [...document.querySelectorAll('#posture-steps li')].map((li) => li.textContent),
    };
  });
  check(drawing.width >= 200 && drawing.height >= 250, `the posture drawing shows (${drawing.width.toFixed(0)} x ${drawing.height.toFixed(0)} px)`);
  check(drawing.armAngles.length === 2 && drawing.armAngles.every((a) => a >= 20 && a <= 30),
    `it draws both arms 20-30° from the body (${drawing.armAngles.map((a) => a.toFixed(1)).join(', ')}°)`);
  check(drawing.feet.length === 2 && drawing.legs.length === 2 &&
      drawing.legs.every((x) => drawing.feet.some((f) => Math.abs(f - x) < 3)),
    `it draws two footprints apart, a foot on each (${drawing.feet.join(', ')})`);
  check(drawing.fists === 2 && drawing.headLevel, 'it draws fists and the head level');
  check(drawing.steps.length === 5 && /footprints/.test(drawing.steps[0]) && /20–30°/.test(drawing.steps[1]),
    `the instruction's five steps are listed (${drawing.steps.length})`);
  await (await page.$('#posture')).screenshot({ path: path.join(ARTIFACTS, '0-posture.png') });

  // A wrong token is refused.
  await page.type('#token', 'not-the-device-token-not-the-device-token');
  await page.click('#login-button');
  await page.waitForFunction(() => document.getElementById('message').textContent.includes('Wrong token'));
  check(true, 'a wrong token is refused');
  check(await page.$eval('#scan-button', (b) => b.disabled), 'no scan button without a login');
  await page.screenshot({ path: path.join(ARTIFACTS, '1-wrong-token.png') });

  // Log in; start a scan; follow it to 100 %.
  await page.type('#token', TOKEN);
  await page.click('#login-button');
  await page.waitForFunction(() => !document.getElementById('session').hidden);
  check(true, 'logged in with the device token');
  await page.waitForFunction(() => !document.getElementById('scan-button').disabled);
  await page.click('#scan-button');
  const seen = new Set();
  await until('the scan to end', async () => {
    const [progress, state] = await page.evaluate(() => [
      document.getElementById('progress-text').textContent,
      document.getElementById('state').textContent]);
    seen.add(progress);
    return ['done', 'fault', 'aborted'].includes(state) ? state : null;
  }, 300000);
  const state = await page.$eval('#state', (e) => e.textContent);
  const progress = await page.$eval('#progress-text', (e) => e.textContent);
  check(state === 'done', `the scan ends done (${state})`);
  check(progress === '100 %', `the progress reaches 100 % (${progress}; seen ${[...seen].join(', ')})`);
  check(seen.size >= 3, `the progress moved while scanning (${seen.size} values)`);
  await page.screenshot({ path: path.join(ARTIFACTS, '2-scanned.png') });

  // Listed; downloaded byte-identical.
  const row = await page.waitForSelector('#scan-rows tr[data-id]');
  const id = await row.evaluate((e) => e.dataset.id);
  const stored = path.join(dir, 'data', `${id}.mscan`);
  check(fs.existsSync(stored), `the scan ${id} is listed and stored`);
  await page.click(`#scan-rows tr[data-id="${id}"] button[data-action="download"]`);
  const downloaded = path.join(downloads, `${id}.mscan`);
  await until('the download', () => fs.existsSync(downloaded) &&
      fs.statSync(downloaded).size === fs.statSync(stored).size, 60000);
  check(sha256(downloaded) === sha256(stored), 'the downloaded archive is byte-identical');

  // The live preview: a PNG with the peaks drawn, only while ticked.
  await page.click('#preview-on');
  await page.waitForFunction(() => {
    const img = document.getElementById('preview');
    return !img.hidden && img.complete && img.naturalWidth > 0;
  }, { timeout: 30000 });
  const previewWidth = await page.$eval('#preview', (img) => img.naturalWidth);
  check(previewWidth === 512, `the live preview shows the camera at half size (${previewWidth} px)`);
  await page.click('#preview-lasers');
  await page.waitForFunction(() => /^[1-9]\d* peaks/.test(document.getElementById('preview-note').textContent),
    { timeout: 30000 });
  check(true, `the lit preview has peaks drawn (${await page.$eval('#preview-note', (e) => e.textContent)})`);
  await page.screenshot({ path: path.join(ARTIFACTS, '3-preview.png') });
  await page.click('#preview-on');  // off: no more captures
  await new Promise((resolve) => setTimeout(resolve, 1500));
  const before = requests.filter((u) => u.includes('/api/v1/preview')).length;
  await new Promise((resolve) => setTimeout(resolve, 2500));
  const after = requests.filter((u) => u.includes('/api/v1/preview')).length;
  check(after === before, `no preview requests while it is off (${after - before} in 2.5 s)`);

  // Processed on the host, uploaded, shown.
  const archive = path.join(dir, 'fetched.mscan');
  r = mirrorscan(['device', 'fetch', id, '--out', archive, '--host', host]);
  if (r.status !== 0) throw new Error(`fetch: ${r.stderr}`);
  const started = Date.now();
  r = mirrorscan(['process', archive, '--calibration', path.join(truth, 'calibration.json'),
    '--out', path.join(dir, 'result'), '--upload', host]);
  check(r.status === 0, `mirrorscan process --upload exits 0 (${r.status}; ${((Date.now() - started) / 1000).toFixed(0)} s) ${r.status ? r.stderr : ''}`);
  // The token stays in this tab's session. (Not networkidle: the event stream stays open.)
  await page.reload({ waitUntil: 'domcontentloaded' });
  // The list is redrawn after the login and when the stream's first event names the
  // ended scan: click by selector once it has settled.
  const showButton = `#scan-rows tr[data-id="${id}"] button[data-action="show"]`;
  await page.waitForSelector(showButton);
  await new Promise((resolve) => setTimeout(resolve, 1500));
  await page.click(showButton);
  await page.waitForFunction(() => document.querySelectorAll('#previews img').length >= 7 &&
      [...document.querySelectorAll('#previews img')].every((img) => img.complete && img.naturalWidth > 0),
  { timeout: 60000 });
  check(true, `the previews show (${await page.$$eval('#previews img', (l) => l.map((i) => i.dataset.name).join(', '))})`);
  // The page fetches measurements.json after it has placed the previews.
  await page.waitForFunction(() => document.querySelectorAll('#measurements tbody tr').length > 0,
    { timeout: 30000 }).catch(() => {});
  const measured = await page.$$eval('#measurements tbody tr', (rows) => rows.map((tr) => tr.textContent));
  // Each row a value in cm or the reason it is withheld (a hole, merged arms, ...).
  const rows = await page.$$eval('#measurements tbody tr', (list) =>
    list.map((tr) => [...tr.children].map((td) => td.textContent)));
  check(rows.length >= 5 && rows.every(([, value, note]) => / cm$/.test(value) || note.length > 0),
    `the measurements show (${rows.length} rows, ${rows.filter((r) => / cm$/.test(r[1])).length} with a value; ${measured.slice(0, 3).join(' | ')})`);
  // The pose check: the mannequin stands turned 25° to its left, so the page flags the
  // scan and shows what to say, as summary.json has it.
  const summary = JSON.parse(fs.readFileSync(path.join(dir, 'result', 'summary.json'), 'utf8'));
  await page.waitForFunction(() => !document.getElementById('pose').hidden, { timeout: 30000 });
  const shownPose = await page.evaluate(() => ({
    verdict: document.getElementById('pose-verdict').textContent,
    advice: [...document.querySelectorAll('#pose-advice li')].map((li) => li.textContent),
    figures: [...document.querySelectorAll('#pose-figures tr')].map((tr) => tr.dataset.figure),
    off: [...document.querySelectorAll('#pose-figures tr.pose-off')].map((tr) => tr.dataset.figure),
  }));
  check(summary.pose && summary.pose.within_protocol === false && summary.pose.advice.length > 0,
    `the mannequin's scan is off the posture (${JSON.stringify(summary.pose && summary.pose.advice)})`);
  check(/off the standard scanning posture/.test(shownPose.verdict), `the page says so (${shownPose.verdict})`);
  check(JSON.stringify(shownPose.advice) === JSON.stringify(summary.pose.advice) &&
      shownPose.advice.some((a) => /Turn about 25° to your right to face the camera/.test(a)),
    `the page shows the advice (${shownPose.advice.join(' | ')})`);
  check(shownPose.figures.length === 7 &&
      JSON.stringify(shownPose.off) === JSON.stringify(summary.pose.off_protocol.filter((k) => shownPose.figures.includes(k))),
    `the figures show, the off ones marked (${shownPose.off.join(', ')})`);
  await (await page.$('#pose')).screenshot({ path: path.join(ARTIFACTS, '4-pose.png') });
  await page.waitForFunction(() => Number(document.getElementById('viewer').dataset.triangles) > 1000,
    { timeout: 60000 });
  // Non-blank: the drawn mesh covers a good part of the canvas in colours far from the
  // background's.
  const coverage = await page.evaluate(() => {
    const canvas = document.getElementById('viewer');
    const copy = document.createElement('canvas');
    copy.width = canvas.width;
    copy.height = canvas.height;
    const context = copy.getContext('2d');
    context.drawImage(canvas, 0, 0);
    const { data } = context.getImageData(0, 0, copy.width, copy.height);
    let lit = 0;
    for (let i = 0; i < data.length; i += 4) {
      if (Math.abs(data[i] - 0x1b) + Math.abs(data[i + 1] - 0x21) + Math.abs(data[i + 2] - 0x27) > 60) lit += 1;
    }
    return lit / (data.length / 4);
  });
  check(coverage > 0.03 && coverage < 0.9, `the 3D viewer shows the body (${(coverage * 100).toFixed(1)} % of the canvas)`);
  const triangles = await page.$eval('#viewer', (c) => c.dataset.triangles);
  check(true, `the viewer loaded mesh.ply (${triangles} triangles)`);
  await page.evaluate(() => document.getElementById('result').scrollIntoView());
  await page.screenshot({ path: path.join(ARTIFACTS, '4-result.png'), fullPage: true });

  // Offline: nothing but the device was asked for anything; the token never in a URL.
  const foreign = requests.filter((u) => !u.startsWith(`http://${host}/`) && !u.startsWith('blob:') && !u.startsWith('data:'));
  check(foreign.length === 0, `every request goes to the device (${foreign.slice(0, 3).join(', ') || 'none elsewhere'})`);
  check(requests.every((u) => !u.includes(TOKEN)), 'the token is in no URL');

  // Delete: gone from the list and from the store, results with it.
  await page.click(`#scan-rows tr[data-id="${id}"] button[data-action="delete"]`);
  await page.waitForFunction((scan) => !document.querySelector(`#scan-rows tr[data-id="${scan}"]`), {}, id);
  check(!fs.existsSync(stored) && !fs.existsSync(path.join(dir, 'data', `${id}.results`)),
    'delete removes the scan and its results');
  await page.screenshot({ path: path.join(ARTIFACTS, '5-deleted.png') });
}

try {
  await main();
} catch (error) {
  console.log(`FAIL ${error.stack || error}`);
  failures += 1;
} finally {
  if (browser) await browser.close();
  daemon.kill('SIGTERM');
  await new Promise((resolve) => daemon.once('exit', resolve));
  if (failures > 0) console.log(fs.readFileSync(path.join(dir, 'daemon.log'), 'utf8').slice(-4000));
  fs.rmSync(dir, { recursive: true, force: true });
}
console.log(failures === 0 ? 'web_browser_test: passed' : `web_browser_test: ${failures} failure(s)`);
process.exit(failures === 0 ? 0 : 1);
