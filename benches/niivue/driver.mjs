// NiiVue side of benches/niivue-side-by-side.sh: one cold run of page.html in a fresh headless
// Chromium (fresh --user-data-dir, so no shader or HTTP cache survives), printing one JSON line:
// the WebGL renderer string, the first rendered frame (from navigation start, and from browser
// launch), the frame times, and writing NiiVue's canvas screenshot as PNG.
// Usage: node driver.mjs CACHE_DIR BASE_URL VOL_URL WxH FRAMES ANGLE PNG_OUT [AZIMUTH ELEVATION]
//   NV_PROBE=frame (environment): page.html waits for any drawn pixel, not the centre's.
//   ANGLE: ANGLE's backend: swiftshader, gl-egl (Mesa llvmpipe through EGL), vulkan (lavapipe).
import { createRequire } from 'node:module'
import { mkdtempSync, rmSync, writeFileSync } from 'node:fs'
import { tmpdir } from 'node:os'
import { join } from 'node:path'

const [cache, base, vol, size, frames, angle, pngOut, az, el] = process.argv.slice(2)
const { chromium } = createRequire(join(cache, 'package.json'))('playwright-core')
const [w, h] = size.split('x').map(Number)
const angleFlags = ['--use-gl=angle', `--use-angle=${angle}`, '--ignore-gpu-blocklist',
  '--enable-unsafe-swiftshader', ...(angle === 'vulkan' ? ['--enable-features=Vulkan'] : [])]
const userDir = mkdtempSync(join(tmpdir(), 'niivue-bench-'))
const t0 = performance.now()
const ctx = await chromium.launchPersistentContext(userDir, {
  executablePath: '/usr/bin/chromium',
  headless: true,
  viewport: { width: w, height: h },
  deviceScaleFactor: 1,
  args: ['--no-sandbox', '--disable-quic', '--no-first-run', '--disable-background-networking',
    '--disable-component-update', '--disable-sync', '--disable-gpu-shader-disk-cache', ...angleFlags],
})
let result
try {
  const page = ctx.pages()[0] ?? await ctx.newPage()
  page.on('console', m => process.stderr.write(`console: ${m.text()}\n`))
  page.on('pageerror', e => process.stderr.write(`pageerror: ${e}\n`))
  const tNav = performance.now()
  let q = `vol=${encodeURIComponent(vol)}&w=${w}&h=${h}&frames=${frames}`
  if (az !== undefined) q += `&azimuth=${az}&elevation=${el}`
  if (process.env.NV_PROBE) q += `&probe=${process.env.NV_PROBE}`
  await page.goto(`${base}/page.html?${q}`)
  await page.waitForFunction(() => window.bench && window.bench.stage !== 'start', null,
    { timeout: 180000, polling: 100 })
  const b = await page.evaluate(() => window.bench)
  if (b.stage !== 'done') throw new Error(`page: ${b.error}`)
  writeFileSync(pngOut, Buffer.from(b.png.split(',')[1], 'base64'))
  delete b.png
  b.launchMs = tNav - t0
  b.firstFrameFromLaunchMs = tNav - t0 + b.tFirstFrame
  result = { ok: true, angle, size, vol, ...b }
} catch (e) {
  result = { ok: false, angle, size, vol, error: String(e) }
} finally {
  await ctx.close()
  rmSync(userDir, { recursive: true, force: true })
}
console.log(JSON.stringify(result))
