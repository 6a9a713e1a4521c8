// The one way photomill's browser checks start Debian's headless Chromium through playwright-core
// (no browser download): found, or the check skipped (exit 77; an error when CI is set, where the
// browser checks must run); a throw-away profile, removed by close().
import { createRequire } from 'node:module';
import { existsSync, mkdtempSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import path from 'node:path';

// Returns { context, page, close } for `tag` (the check's name in messages); `viewport` optional.
export async function launchChromium(tag, viewport) {
  const chromiumPath = process.env.PHOTOMILL_CHROMIUM || '/usr/bin/chromium';
  const skip = (why) => {
    if (process.env.CI) {
      console.error(`${tag}: ${why} (CI is set: the browser check must run)`);
      process.exit(1);
    }
    console.error(`${tag}: skipped: ${why} (scripts/install-deps.sh --tests installs it)`);
    process.exit(77);
  };
  if (!existsSync(chromiumPath)) skip(`no Chromium at ${chromiumPath}`);
  let chromium;
  try {
    const require = createRequire(import.meta.url);
    ({ chromium } = require('playwright-core'));
  } catch {
    skip('no playwright-core in tests/browser/node_modules');
  }
  const profile = mkdtempSync(path.join(tmpdir(), 'photomill-chromium-'));
  let context;
  try {
    context = await chromium.launchPersistentContext(profile, {
      executablePath: chromiumPath,
      headless: true,
      ...(viewport ? { viewport } : {}),
      args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
             '--disable-background-networking', '--disable-component-update', '--disable-sync'],
    });
  } catch (e) {
    rmSync(profile, { recursive: true, force: true });
    throw e;
  }
  const page = context.pages()[0] || await context.newPage();
  const close = async () => {
    await context.close();
    rmSync(profile, { recursive: true, force: true });
  };
  return { context, page, close };
}
