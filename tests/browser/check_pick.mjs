// Drives pick's page (issue 29) in Debian's headless Chromium through playwright-core, as a user
// would: for each of the given points, in each of the given photos in turn, the photo is shown at
// ZOOM screen pixels per image pixel centred on the point's true projection, and the nearest screen
// pixel to it is clicked (a real mouse click through the page's handlers). Checked on the way:
// before a point is marked in its second photo, the epipolar curve the page holds for it passes
// within 1 px of the true projection; before its third, the predicted position is within 1 px;
// the marks' crosses are drawn; no console error and no request beyond the server. Then a
// screenshot, the keyboard (N, a click, Ctrl+Z, ]), and the page's Finish button. The caller triangulates the saved file.
// Usage: node check_pick.mjs URL TRUTH_OBSERVATIONS.csv IDS IMAGES ZOOM SCREENSHOT.png
//   IDS: comma-separated point ids; IMAGES: comma-separated image names as pick shows them.
// Exit 0 ok, 1 a check failed, 77 skipped (no Chromium or playwright-core; never when CI is set).
import { readFileSync } from 'node:fs';
import path from 'node:path';

import { launchChromium } from './chromium.mjs';

const [url, truthPath, idList, imageList, zoomText, screenshot] = process.argv.slice(2);
if (!screenshot) {
  console.error('usage: node check_pick.mjs URL TRUTH.csv IDS IMAGES ZOOM SCREENSHOT.png');
  process.exit(2);
}

const ids = idList.split(',').map(Number);
const images = imageList.split(',');
const zoom = Number(zoomText);
// The true projections: image -> id -> [u, v] (photomill's observations CSV; '#' lines are stamps).
const truth = new Map();
{
  const lines = readFileSync(truthPath, 'utf8').split(/\r?\n/).filter((l) => l && !l.startsWith('#'));
  const head = lines[0].split(',');
  const [ci, cp, cu, cv] = ['image', 'point_id', 'u_px', 'v_px'].map((c) => head.indexOf(c));
  for (const l of lines.slice(1)) {
    const f = l.split(',');
    const name = path.basename(f[ci]);
    if (!truth.has(name)) truth.set(name, new Map());
    truth.get(name).set(Number(f[cp]), [Number(f[cu]), Number(f[cv])]);
  }
}
const trueUv = (image, id) => {
  const t = truth.get(path.basename(image));
  if (!t || !t.has(id)) throw new Error(`no true projection of point ${id} in ${image}`);
  return t.get(id);
};
// Distance from (u, v) to a polyline, pixels.
const distanceToPolyline = ([u, v], line) => {
  let best = Infinity;
  for (let k = 1; k < line.length; ++k) {
    const [ax, ay] = line[k - 1], [bx, by] = line[k];
    const dx = bx - ax, dy = by - ay, l2 = dx * dx + dy * dy;
    const t = l2 > 0 ? Math.max(0, Math.min(1, ((u - ax) * dx + (v - ay) * dy) / l2)) : 0;
    best = Math.min(best, Math.hypot(ax + t * dx - u, ay + t * dy - v));
  }
  return best;
};

// A fixed pseudo-random sequence (the run is reproducible): a 32-bit linear congruential generator.
let seed = 2029;
const rand = () => ((seed = (Math.imul(seed, 1664525) + 1013904223) >>> 0) / 4294967296);
const problems = [];
const notes = [];
const figures = { epipolar_px: [], predicted_px: [], clicked_px: [] };
let browser;
try {
  browser = await launchChromium('check_pick', { width: 1600, height: 1000 });
  const { page } = browser;
  page.on('console', (m) => { if (m.type() === 'error') problems.push(`console error: ${m.text()}`); });
  page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
  const origin = new URL(url).origin;
  await page.route('**/*', (route) => {
    const u = route.request().url();
    if (u.startsWith(origin + '/')) return route.continue();
    problems.push(`request beyond the server: ${u}`);
    return route.abort();
  });
  await page.goto(url, { waitUntil: 'load' });
  try {
    await page.waitForFunction(() => window.pick && window.pick.ready, null, { timeout: 30000 });
  } catch (e) {
    throw new Error('the page did not become ready; its status: ' + await page.evaluate(() => document.querySelector('#status').textContent));
  }
  const names = await page.evaluate(() => window.pick.state.photos.map((p) => p.name));
  const index = images.map((im) => {
    const i = names.indexOf(im);
    if (i < 0) throw new Error(`pick does not show ${im} (it shows ${names.join(', ')})`);
    return i;
  });
  await page.evaluate(() => { window.pick.refine = document.querySelector('#refine').value; });
  for (const id of ids) {
    await page.evaluate((id) => window.pick.setCurrent(id), id);
    for (let k = 0; k < images.length; ++k) {
      const pane = k % 2;
      const [u, v] = trueUv(images[k], id);
      // Centred on a whole pixel 0-20 px away from the point (as a user pans, not on the truth), so
      // that the point falls between screen pixels and the click carries a human's quantisation.
      const cu = Math.round(u) + Math.round(20 * (rand() - 0.5)), cv = Math.round(v) + Math.round(20 * (rand() - 0.5));
      await page.evaluate(([pane, photo, zoom, u, v]) => window.pick.view(pane, photo, zoom, u, v), [pane, index[k], zoom, cu, cv]);
      await page.evaluate(() => window.pick.refreshGuides());
      const guide = await page.evaluate((pane) => window.pick.panes[pane].guide, pane);
      if (k === 1 || k === 2) {
        const curves = (guide && guide.curves) || [];
        if (!curves.length) problems.push(`point ${id}: no epipolar curve in ${images[k]}`);
        for (const c of curves) {
          const d = Math.min(...c.polylines.map((line) => distanceToPolyline([u, v], line)));
          figures.epipolar_px.push(d);
          if (!(d <= 1)) problems.push(`point ${id}: the epipolar curve from ${c.from_image} passes ${d.toFixed(3)} px from the true projection in ${images[k]}`);
        }
      }
      if (k === 2) {
        const p = guide && guide.predicted_px;
        const d = p ? Math.hypot(p[0] - u, p[1] - v) : Infinity;
        figures.predicted_px.push(d);
        if (!(d <= 1)) problems.push(`point ${id}: predicted position ${JSON.stringify(p)} is ${d.toFixed(3)} px from the truth in ${images[k]}`);
      }
      const s = await page.evaluate(([pane, u, v]) => window.pick.toScreen(pane, u, v), [pane, u, v]);
      const x = Math.round(s.x), y = Math.round(s.y);
      const before = await page.evaluate(() => window.pick.lastMark);
      await page.mouse.click(x, y);
      await page.waitForFunction(([before, id, name]) => {
        const m = window.pick.lastMark;
        return m && m !== before && m.point_id === id && m.image === name &&
               window.pick.state.points.some((pt) => pt.point_id === id && pt.observations.some((o) => o.image === name));
      }, [before, id, images[k]], { timeout: 10000 });
      const m = await page.evaluate(() => window.pick.lastMark);
      figures.clicked_px.push(Math.hypot(m.u_px - u, m.v_px - v));
      // The mark's cross (where the mark landed, after refinement): the arm 5 screen pixels right
      // of it is drawn in the current point's yellow.
      const colour = await page.evaluate(([pane, u, v]) => {
        const c = document.querySelectorAll('.pane canvas')[pane];
        const r = c.getBoundingClientRect(), dpr = window.devicePixelRatio || 1;
        const s = window.pick.toScreen(pane, u, v);
        window.pick.draw();
        const d = c.getContext('2d').getImageData(Math.round((s.x + 5 - r.left) * dpr), Math.round((s.y - r.top) * dpr) - 1, 1, 3).data;
        // Yellowness of the most yellow of the three pixels across the arm: min(red, green) - blue.
        return Math.max(...[0, 4, 8].map((k) => Math.min(d[k], d[k + 1]) - d[k + 2]));
      }, [pane, m.u_px, m.v_px]);
      if (!(colour > 120)) problems.push(`point ${id} in ${images[k]}: no yellow cross at the mark (yellowness ${colour})`);
      if (m.note) notes.push(`${id} ${images[k]}: ${m.note}`);
    }
  }
  await page.screenshot({ path: screenshot });
  // Keyboard: N gives the next unused id; a click marks it; Ctrl+Z undoes the mark; ] shows the
  // next photo in the pane under the mouse. The saved file ends as it was.
  const box = await page.locator('.pane canvas').first().boundingBox();
  await page.mouse.move(box.x + box.width / 2 + 0.5, box.y + box.height / 2 + 0.5);
  await page.keyboard.press('n');
  const fresh = await page.evaluate(() => [window.pick.currentId, window.pick.state.next_free_id]);
  if (fresh[0] !== fresh[1] || ids.includes(fresh[0])) problems.push(`N gave point id ${fresh[0]}, not the next unused one (${fresh[1]})`);
  const before = await page.evaluate(() => window.pick.lastMark);
  await page.mouse.click(box.x + box.width / 2, box.y + box.height / 2);
  await page.waitForFunction((b) => window.pick.lastMark !== b, before, { timeout: 10000 });
  await page.waitForFunction((id) => window.pick.state.points.some((p) => p.point_id === id), fresh[0], { timeout: 10000 });
  await page.keyboard.press('Control+z');
  await page.waitForFunction((id) => !window.pick.state.points.some((p) => p.point_id === id), fresh[0], { timeout: 10000 })
    .catch(() => problems.push('Ctrl+Z did not undo the last mark'));
  const shown = await page.evaluate(() => window.pick.panes[0].photo);
  await page.keyboard.press(']');
  const next = await page.evaluate(() => window.pick.panes[0].photo);
  if (next !== (shown + 1) % names.length) problems.push(`] showed photo ${next} after ${shown}`);
  const errorText = await page.evaluate(() => window.pick.error);
  if (errorText) problems.push(`the page reported an error: ${errorText}`);
  await page.click('#finish');
  await page.waitForFunction(() => window.pick.finished, null, { timeout: 10000 });
  const max = (a) => (a.length ? Math.max(...a) : NaN);
  console.error(`check_pick: ${ids.length} points x ${images.length} photos clicked at zoom ${zoom}; ` +
                `click to truth max ${max(figures.clicked_px).toFixed(4)} px; epipolar curves max ${max(figures.epipolar_px).toFixed(4)} px ` +
                `(${figures.epipolar_px.length}); predicted max ${max(figures.predicted_px).toFixed(4)} px; ${problems.length} problems`);
} catch (e) {
  problems.push(`the browser run failed: ${e.message.split('\n')[0]}`);
} finally {
  if (browser) await browser.close();
}
for (const n of notes) console.error(`check_pick: note: ${n}`);
for (const p of problems) console.error(`check_pick: ${p}`);
process.exit(problems.length ? 1 : 0);
