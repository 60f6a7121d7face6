#!/usr/bin/env bash
# Builds what a run on the lent GPU machine needs (../shared/GPU.md): the release binary and the
# GPU test binaries (stripped) in .gpu/, and the Vulkan loader / validation-layer packages in
# .gl/. Both folders are git-ignored via .git/info/exclude and travel as `carry`.
# Then, with the device tool: run(command="bash benches/device-run.sh", carry=[".gl", ".gpu"]).
set -euo pipefail
cd "$(dirname "$0")/.."
exclude="$(git rev-parse --git-dir)/info/exclude"
mkdir -p "$(dirname "$exclude")"
grep -qx '/.gl/' "$exclude" 2>/dev/null || printf '/.gl/\n/.gpu/\n' >> "$exclude"
mkdir -p .gl .gpu
cp ../shared/gpu/debs/*.deb .gl/
# spirv-val for the shader test (the device machine has no package registry).
(cd .gl && apt-get download spirv-tools >/dev/null 2>&1) || echo "note: spirv-tools not downloaded; the shaders test will fail there"
cargo build --release
rm -f .gpu/*
cp target/release/morphray .gpu/
executables=$(cargo test --release --no-run --message-format=json 2>/dev/null |
    python3 -c 'import json,sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m.get("executable") and m["target"]["kind"] != ["bin"]:
        print(m["target"]["name"], m["target"]["kind"][0], m["executable"])')
while read -r name kind path; do
    case "$name/$kind" in
        morphray/lib) cp "$path" .gpu/lib_tests ;;
        # CPU-only tests and the viewer's (it needs a display server) stay here.
        fuzz_regressions/test|nifti_*/test|phantom/test|reference*/test|peaks/test|viewer/test) ;;
        */test) cp "$path" ".gpu/$name" ;;
    esac
done <<< "$executables"
strip .gpu/*
ls -la .gpu .gl
