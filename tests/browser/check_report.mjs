// Opens a job's report.html in Debian's headless Chromium (through playwright-core, no browser
// download) and checks what issue 27 asks of it: no console error, no failed or network request,
// every picture decoded (naturalWidth > 0), every link of the contents landing on its anchor, and
// the headline figures on the page equal to the values of the job's JSON reports (4 significant
// digits).
// Usage: node check_report.mjs REPORT.html JOB_FOLDER
// Exit 0 ok, 1 a check failed, 77 skipped (no Chromium or playwright-core; never when CI is set).
import { readFileSync } from 'node:fs';
import path from 'node:path';
import { pathToFileURL } from 'node:url';

import { launchChromium } from './chromium.mjs';

const [reportPath, jobDir] = process.argv.slice(2);
if (!reportPath || !jobDir) {
  console.error('usage: node check_report.mjs REPORT.html JOB_FOLDER');
  process.exit(2);
}

// The headline figures every complete job's page must show (a subset of report/report.cpp's list:
// one or more per stage).
const required = [
  'calib.json:rms_px',
  'triangulate.json:points',
  'triangulate.json:final_rms_px',
  'fitsurf.json:residuals.rms_mm',
  'fitsurf.json:selection.fitted_points',
  'toolpath.json:path.feed_length_mm',
  'toolpath.json:gouges.points',
];
const pictures = ['calib.png', 'cloud.png', 'surface.png', 'path.png'];

const problems = [];
let browser;
try {
  browser = await launchChromium('check_report');
  const { page } = browser;
  page.on('console', (m) => { if (m.type() === 'error') problems.push(`console error: ${m.text()}`); });
  page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
  page.on('requestfailed', (r) => problems.push(`request failed: ${r.url().slice(0, 80)}`));
  // The page must need no network: any request but the file itself and its data: URIs fails.
  await page.route('**/*', (route) => {
    const url = route.request().url();
    if (url.startsWith('file:') || url.startsWith('data:')) return route.continue();
    problems.push(`network request: ${url}`);
    return route.abort();
  });
  await page.goto(pathToFileURL(path.resolve(reportPath)).href, { waitUntil: 'load' });
  const images = await page.evaluate(() => Array.from(document.images, (i) => ({
    alt: i.alt, complete: i.complete, width: i.naturalWidth, height: i.naturalHeight })));
  for (const i of images) {
    if (!i.complete || i.width === 0) problems.push(`broken image: ${i.alt}`);
  }
  for (const p of pictures) {
    if (!images.some((i) => i.alt === p)) problems.push(`picture not on the page: ${p}`);
  }
  // Every link of the contents lands on its anchor.
  const dangling = await page.evaluate(() => Array.from(document.querySelectorAll('a[href^="#"]'),
    (a) => a.getAttribute('href').slice(1)).filter((id) => !document.getElementById(id)));
  for (const id of dangling) problems.push(`a link to nowhere: #${id}`);
  const figures = await page.evaluate(() => Array.from(document.querySelectorAll('[data-json]'),
    (e) => [e.dataset.json, e.textContent, e.checkVisibility ? e.checkVisibility() : true]));
  const text = await page.evaluate(() => document.body.innerText);
  const shown = new Map(figures.map(([key, t, visible]) => [key, { t, visible }]));
  for (const key of required) {
    if (!shown.has(key)) problems.push(`headline figure not on the page: ${key}`);
  }
  const reports = new Map();
  for (const [key, { t, visible }] of shown) {
    const [file, dotted] = key.split(':');
    if (!reports.has(file)) reports.set(file, JSON.parse(readFileSync(path.join(jobDir, file), 'utf8')));
    const value = dotted.split('.').reduce((o, k) => (o == null ? undefined : o[k]), reports.get(file));
    const number = Number(t);
    if (typeof value !== 'number') {
      problems.push(`${key}: the page shows ${t}, the report has no number there`);
    } else if (!(Math.abs(number - value) <= 5e-4 * Math.abs(value))) {
      problems.push(`${key}: the page shows ${t}, the report says ${value}`);
    } else if (!visible || !text.includes(t)) {
      problems.push(`${key}: ${t} is not in the page's visible text`);
    }
  }
  console.error(`check_report: ${images.length} pictures, ${shown.size} headline figures checked, ` +
                `${problems.length} problems`);
} catch (e) {
  problems.push(`the browser run failed: ${e.message.split('\n')[0]}`);
} finally {
  if (browser) await browser.close();
}
for (const p of problems) console.error(`check_report: ${p}`);
process.exit(problems.length ? 1 : 0);
