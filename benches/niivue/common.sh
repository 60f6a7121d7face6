# NiiVue in headless Chromium, shared by benches/niivue-side-by-side.sh (timing) and
# tools/figures/side-by-side.sh (pictures). Source it (bash); it defines functions only:
#
#   niivue_install            Debian's chromium (apt-get) and, under $NIIVUE_CACHE, @niivue/niivue,
#                             playwright-core (drives /usr/bin/chromium; no browser download) and
#                             esbuild (bundles NiiVue's ES modules for a plain static page) from
#                             npm, versions pinned below; idempotent.
#   niivue_serve              a fresh $NV_WORK folder (removed on exit) with the bundle and
#                             page.html, served on 127.0.0.1:$NV_PORT (python3 -m http.server).
#   niivue_add NAME FILE      serves FILE as NAME.nii.gz.
#   niivue_single_gzip FILE   rewrites a morphray-written .nii.gz as one gzip member (see below).
#   niivue_run NAME WxH PNG [AZ EL]  one fresh browser: a JSON line on stdout, NiiVue's picture.
#   niivue_versions           "chromium X, @niivue/niivue Y" for provenance lines.
#
# Decisions: everything served lives in the run's own folder, so two runs (or two worktrees) never
# share a served file, a port or a phantom. Chromium runs headless with ANGLE on Mesa llvmpipe
# (--use-angle=gl-egl; $NV_ANGLE to change: swiftshader works too, vulkan did not initialise
# WebGL2 here).
NIIVUE_VERSION=1.0.0-rc.9 PLAYWRIGHT_VERSION=1.57.0 ESBUILD_VERSION=0.25.12
NIIVUE_CACHE=${NIIVUE_CACHE:-$HOME/.cache/morphray/niivue}
NV_ANGLE=${NV_ANGLE:-gl-egl}
NV_FRAMES=${NV_FRAMES:-6}
NV_LOG=${NV_LOG:-/dev/null}
NV_DIR=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)

niivue_install() {
  command -v node >/dev/null && command -v npm >/dev/null \
    || { echo "error: node and npm are needed for NiiVue (apt-get install nodejs npm)" >&2; return 2; }
  if ! command -v chromium >/dev/null; then
    apt-get update -qq && apt-get install -y -qq chromium \
      || { echo "error: chromium is missing and apt-get could not install it (apt-get install chromium)" >&2; return 2; }
  fi
  mkdir -p "$NIIVUE_CACHE"
  if [ "$(node -p "try{require('$NIIVUE_CACHE/node_modules/@niivue/niivue/package.json').version}catch(e){''}")" != "$NIIVUE_VERSION" ] \
     || [ ! -d "$NIIVUE_CACHE/node_modules/playwright-core" ] || [ ! -x "$NIIVUE_CACHE/node_modules/.bin/esbuild" ]; then
    [ -f "$NIIVUE_CACHE/package.json" ] || echo '{"name":"morphray-niivue-bench","private":true}' > "$NIIVUE_CACHE/package.json"
    (cd "$NIIVUE_CACHE" && npm install --no-audit --no-fund "@niivue/niivue@$NIIVUE_VERSION" \
       "playwright-core@$PLAYWRIGHT_VERSION" "esbuild@$ESBUILD_VERSION") \
      || { echo "error: npm could not install NiiVue into $NIIVUE_CACHE (network? see npm's message above)" >&2; return 2; }
  fi
}

niivue_serve() {
  NV_PORT=${PORT:-$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')}
  NV_WORK=$(mktemp -d)
  mkdir -p "$NV_WORK/www"
  echo "export { default } from '@niivue/niivue/webgl2'" > "$NV_WORK/entry.mjs"
  NODE_PATH="$NIIVUE_CACHE/node_modules" "$NIIVUE_CACHE/node_modules/.bin/esbuild" "$NV_WORK/entry.mjs" \
     --bundle --format=esm --platform=browser --log-level=error --outfile="$NV_WORK/www/niivue.bundle.js"
  ln -sfn "$NV_DIR/page.html" "$NV_WORK/www/page.html"
  (cd "$NV_WORK/www" && exec python3 -m http.server "$NV_PORT" --bind 127.0.0.1 >"$NV_WORK/http.log" 2>&1) &
  NV_HTTP_PID=$!
  trap 'kill $NV_HTTP_PID 2>/dev/null; rm -rf "$NV_WORK"' EXIT
  sleep 1
}

niivue_add() { ln -sfn "$2" "$NV_WORK/www/$1.nii.gz"; }

# morphray writes .nii.gz as several 1 MiB gzip members (parallel inflation); NiiVue 1.0.0-rc.9
# inflates only the first member and rejects the truncated image ("infinite image"). Both
# renderers get the same single-member copy (same header, slope 1 and intercept 0, and voxels).
niivue_single_gzip() {
  python3 - "$1" <<'PYEOF'
import gzip, struct, sys
b = bytearray(gzip.open(sys.argv[1]).read())
b[112:120] = struct.pack("<ff", 1.0, 0.0)
gzip.open(sys.argv[1], "wb", compresslevel=1).write(bytes(b))
PYEOF
}

niivue_run() { # NAME WxH PNG [AZ EL] -> one JSON line on stdout
  node "$NV_DIR/driver.mjs" "$NIIVUE_CACHE" "http://127.0.0.1:$NV_PORT" "$1.nii.gz" "$2" "$NV_FRAMES" \
    "$NV_ANGLE" "$3" "${@:4}" 2>>"$NV_LOG"
}

niivue_versions() {
  echo "$(chromium --version | tail -1), @niivue/niivue $NIIVUE_VERSION (ANGLE $NV_ANGLE)"
}
