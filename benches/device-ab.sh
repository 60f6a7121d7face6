#!/usr/bin/env bash
# Two builds side by side on the lent H200, one call: the raymarch's frame of build A (.ab/morphray-a.xz)
# and build B (.sv/morphray.xz, the current one) on MNI152 and the default phantom, at 1920x1080
# and 500x500, shaded (the default scene), alternated A, B per round, 3 rounds of 50 frames.
# Used for a change that should move the frame on one device class and not another (issue 33:
# the transfer-function table as a texel buffer, a lavapipe gain, neutral here?).
# Build here: for the old tree, cargo build --release; strip; xz -9e > .ab/morphray-a.xz; then the new
# tree likewise into .sv/morphray.xz (and .sv/mni.nii.xz: the MNI152 copy, xz);
# run(command="bash benches/device-ab.sh", carry=[".glmin", ".sv", ".ab"]).
set -uo pipefail
# shellcheck source=benches/device-common.sh
source benches/device-common.sh
python3 -c 'import lzma,shutil,sys; shutil.copyfileobj(lzma.open(sys.argv[1]), open(sys.argv[2], "wb"))' \
    .ab/morphray-a.xz /tmp/morphray-a && chmod +x /tmp/morphray-a
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$OUT/ab.txt"
$M phantom -o "$V/phantom.nii.gz" > /dev/null
for round in 1 2 3; do
    for vol in mni152 phantom; do
        for size in 1920x1080 500x500; do
            for build in a b; do
                bin=$M
                [ $build = a ] && bin=/tmp/morphray-a
                $bin bench "$V/$vol.nii.gz" --size $size --frames 50 --repeat 1 --trials 0 \
                    > "$RAW/$vol-$size-$build-r$round.txt" 2>&1
                echo "$vol $size $build r$round: $(grep -E '^raymarch:' "$RAW/$vol-$size-$build-r$round.txt" | cut -c1-100)" |
                    tee -a "$OUT/ab.txt"
            done
        done
    done
done
tar czf "$OUT/raw.tgz" -C "$RAW" .
