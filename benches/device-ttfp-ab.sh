#!/usr/bin/env bash
# Time to first pixel of two builds on the lent H200, one call: build A (.ab/morphray-a.xz) and
# build B (.sv/morphray.xz), the default phantom at 1920x1080, `bench --trials 5` (cold: an empty
# pipeline cache per process; warm: the cache the cold trials wrote), alternated A, B per round,
# 2 rounds. For a change that adds a pipeline or a pass to the first frame's path (issue 33 item
# 3: the distance map's pass rides with the occupancy pipelines).
#   run(command="bash benches/device-ttfp-ab.sh", carry=[".glmin", ".sv", ".ab"])
set -uo pipefail
# shellcheck source=benches/device-common.sh
source benches/device-common.sh
python3 -c 'import lzma,shutil,sys; shutil.copyfileobj(lzma.open(sys.argv[1]), open(sys.argv[2], "wb"))' \
    .ab/morphray-a.xz /tmp/morphray-a && chmod +x /tmp/morphray-a
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$OUT/ttfp.txt"
for round in 1 2; do
    for build in a b; do
        bin=$M
        [ $build = a ] && bin=/tmp/morphray-a
        $bin bench --size 1920x1080 --frames 10 --repeat 1 --trials 5 \
            > "$RAW/ttfp-$build-r$round.txt" 2>&1
        echo "$build r$round: $(grep -E 'total \(spawn' "$RAW/ttfp-$build-r$round.txt" | tr -s ' ' | cut -c1-110)" |
            tee -a "$OUT/ttfp.txt"
    done
done
tar czf "$OUT/raw.tgz" -C "$RAW" .
