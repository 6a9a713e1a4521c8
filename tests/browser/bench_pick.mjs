// Benchmark (issue 29): how soon pick's page is usable. Opens URL in Debian's headless Chromium
// (playwright-core) and prints, in milliseconds: from navigation to the page ready (state loaded,
// both panes showing their full-size photo, decoded), to every thumbnail decoded, and the time to
// switch a pane to another full-size photo (mean of SWITCHES switches). Not a test: figures only.
// Usage: node bench_pick.mjs URL [SWITCHES]
import { launchChromium } from './chromium.mjs';

const [url, switchesText] = process.argv.slice(2);
const switches = Number(switchesText || 10);
const browser = await launchChromium('bench_pick', { width: 1600, height: 1000 });
try {
  const { page } = browser;
  const t0 = Date.now();
  await page.goto(url, { waitUntil: 'commit' });
  await page.waitForFunction(() => window.pick && window.pick.ready, null, { timeout: 60000, polling: 10 });
  const ready = Date.now() - t0;
  await page.waitForFunction(() => Array.from(document.querySelectorAll('#thumbs img')).every((i) => i.complete && i.naturalWidth > 0),
                             null, { timeout: 60000, polling: 10 });
  const thumbs = Date.now() - t0;
  const n = await page.evaluate(() => window.pick.state.photos.length);
  const t1 = Date.now();
  for (let k = 0; k < switches; ++k) {
    await page.evaluate((photo) => window.pick.view(0, photo, 1, 1000, 750), (2 + k) % n);
  }
  const perSwitch = (Date.now() - t1) / switches;
  console.log(`photos ${n} ready_ms ${ready} thumbnails_ms ${thumbs} switch_ms ${perSwitch.toFixed(1)}`);
} finally {
  await browser.close();
}
