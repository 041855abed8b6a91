#!/usr/bin/env node
// browser-check.js URL OUTDIR [--wireframe] [--lod K]: opens the player page at URL in headless
// Debian Chromium (playwright-core, CHROMIUM or /usr/bin/chromium), waits until every frame is
// decoded, screenshots frame 0, plays until the frame changed twice, pauses, screenshots
// again, goes to the last frame, switches
// to level of detail 0 and screenshots the last frame again, and prints a JSON summary (the page's state and console errors). The
// pixel checks are the caller's (tests/test_player.py).
import { chromium } from 'playwright-core';
import { mkdirSync } from 'node:fs';

const [url, out, ...rest] = process.argv.slice(2);
const wire = rest.includes('--wireframe');
mkdirSync(out, { recursive: true });
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  headless: true,
  // The machine has no GPU and a closed network: software WebGL, no background connections.
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
    '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run', '--disable-quic'],
});
const result = { console: [] };
try {
  const page = await browser.newPage({ viewport: { width: 640, height: 480 } });
  page.on('console', (m) => { if (m.type() === 'error') result.console.push(m.text()); });
  page.on('pageerror', (e) => result.console.push(String(e)));
  await page.goto(url);
  await page.waitForFunction(() => window.dynmeshPlayer && (window.dynmeshPlayer.state.error
    || (window.dynmeshPlayer.state.frames > 0 && window.dynmeshPlayer.state.decoded === window.dynmeshPlayer.state.frames)), null, { timeout: 120000 });
  result.loaded = await page.evaluate(() => ({ ...window.dynmeshPlayer.state }));
  if (wire) await page.click('#wire');
  await page.evaluate(() => window.dynmeshPlayer.seek(0));
  await page.waitForTimeout(300);
  await page.screenshot({ path: `${out}/frame_first.png` });
  const t0 = Date.now();
  await page.click('#play');
  await page.waitForFunction(() => window.dynmeshPlayer.state.advanced >= 2, null, { timeout: 30000 });
  result.playSeconds = (Date.now() - t0) / 1000;
  await page.click('#play');
  result.paused = await page.evaluate(() => ({ ...window.dynmeshPlayer.state }));
  await page.waitForTimeout(300);
  result.pausedLater = await page.evaluate(() => ({ ...window.dynmeshPlayer.state }));
  await page.screenshot({ path: `${out}/frame_played.png` });
  await page.evaluate(() => window.dynmeshPlayer.seek(window.dynmeshPlayer.state.frames - 1));
  await page.waitForTimeout(300);
  await page.screenshot({ path: `${out}/frame_last.png` });
  result.final = await page.evaluate(() => ({ ...window.dynmeshPlayer.state, status: document.getElementById('status').textContent }));
  // The coarsest level of detail: the page decodes the stream again without subdividing.
  await page.selectOption('#lod', '0');
  await page.waitForFunction(() => {
    const s = window.dynmeshPlayer.state;
    return s.error || (s.lod === 0 && s.decoded === s.frames && s.shown === s.frame);
  }, null, { timeout: 120000 });
  await page.evaluate(() => window.dynmeshPlayer.seek(window.dynmeshPlayer.state.frames - 1));
  await page.waitForTimeout(300);
  await page.screenshot({ path: `${out}/frame_lod0.png` });
  result.lod0 = await page.evaluate(() => ({ ...window.dynmeshPlayer.state }));
} catch (e) {
  result.error = String(e);
} finally {
  await browser.close();
}
console.log(JSON.stringify(result));
