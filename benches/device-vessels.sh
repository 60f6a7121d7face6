#!/usr/bin/env bash
# The vessel channel's cost (issue 15 item 3) and the frame targets on the new phantom (issue 17
# item 4: the phantom gained vessels of known radii and an edema shell), on the lent GPU machine.
# One stripped release binary of this tree in .sv/morphray with the MNI152 copy .sv/mni.nii.gz;
# each `morphray bench` at 1920x1080, step 0.5, 100 orbit frames, three rounds alternated:
# phantom and MNI152 with curvature + shading (the issue's targets), MNI152 with shading and
# the default tissues, and with `--tissues vessels,pathology` (the vesselness pass and the
# raymarch that reads it).
#   run(command="bash benches/device-vessels.sh", carry=[".glmin", ".sv"])
set -uo pipefail
for f in .glmin/lib{vulkan1,egl1,glvnd0,opengl0,gl1,glx0,gles2}_*.deb; do dpkg -x "$f" /; done
ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
OUT=${OUT:-/tmp/morphray-out}
RAW=$(mktemp -d)  # every bench's output, handed back as one archive (the machine returns few files)
mkdir -p "$OUT"
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.mem --format=csv,noheader | tee "$OUT/device.txt"
bench() { # NAME VOLUME ARGS...
    local name=$1 vol=$2
    shift 2
    .sv/morphray bench $vol --trials 0 --frames 100 --repeat 3 --size 1920x1080 "$@" \
        --json "$RAW/$name.json" > "$RAW/$name.txt" 2>&1
    echo "$name: $(grep -E '^raymarch:' "$RAW/$name.txt" | cut -c1-80) | $(grep -E '^vesselness ' "$RAW/$name.txt" | cut -c1-60) | $(grep -E '^empty-space' "$RAW/$name.txt" | cut -c1-60)"
}
for round in 1 2 3; do
    bench "phantom-cs-$round" "" --curvature on --shading on
    bench "mni-cs-$round" .sv/mni.nii.gz --curvature on --shading on
    bench "mni-s-$round" .sv/mni.nii.gz --shading on
    bench "mni-s-vessels-$round" .sv/mni.nii.gz --shading on --tissues vessels,pathology
done 2>&1 | tee "$OUT/summary.txt"
cp "$OUT/device.txt" "$OUT/summary.txt" "$RAW/"
tar czf "$OUT/raw.tgz" -C "$RAW" .
