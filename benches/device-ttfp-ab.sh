#!/usr/bin/env bash
# Time to first pixel of two builds on the lent H200, one call: build A (.ab/morphray-a.xz) and
# build B (.sv/morphray.xz), the default phantom at 1920x1080, `bench --trials 5` (cold: an empty
# pipeline cache per process; warm: the cache the cold trials wrote), alternated A, B per round,
# 2 rounds. For a change that adds a pipeline or a pass to the first frame's path (issue 33 item
# 3: the distance map's pass rides with the occupancy pipelines), or that changes what the driver
# compiles (issue 33 item 2: spirv-opt, B_XZ=.ab/morphray-b.xz).
# Environment: A_XZ, B_XZ (the builds, xz-compressed), VOLUMES (`phantom` and/or `mni152`;
# default phantom).
#   run(command="bash benches/device-ttfp-ab.sh", carry=[".glmin", ".sv", ".ab"])
set -uo pipefail
# shellcheck source=benches/device-common.sh
source benches/device-common.sh
python3 -c 'import lzma,shutil,sys; shutil.copyfileobj(lzma.open(sys.argv[1]), open(sys.argv[2], "wb"))' \
    "${A_XZ:-.ab/morphray-a.xz}" /tmp/morphray-a && chmod +x /tmp/morphray-a
if [ -n "${B_XZ:-}" ]; then
    python3 -c 'import lzma,shutil,sys; shutil.copyfileobj(lzma.open(sys.argv[1]), open(sys.argv[2], "wb"))' \
        "$B_XZ" /tmp/morphray-b && chmod +x /tmp/morphray-b
    M=/tmp/morphray-b
fi
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$OUT/ttfp.txt"
for round in 1 2; do
    for vol in ${VOLUMES:-phantom}; do
        input=""
        [ "$vol" = mni152 ] && input=$V/mni152.nii.gz
        for build in a b; do
            bin=$M
            [ $build = a ] && bin=/tmp/morphray-a
            log="$RAW/ttfp-$vol-$build-r$round.txt"
            # shellcheck disable=SC2086
            $bin bench $input --size 1920x1080 --frames 10 --repeat 1 --trials 5 > "$log" 2>&1
            echo "$vol $build r$round: $(grep -E 'total \(spawn' "$log" | tr -s ' ' | cut -c1-110)" |
                tee -a "$OUT/ttfp.txt"
            echo "$vol $build r$round: $(grep -E 'pipelines.ahead_sum' "$log" | tr -s ' ' | cut -c1-110)" |
                tee -a "$OUT/ttfp.txt"
        done
    done
done
tar czf "$OUT/raw.tgz" -C "$RAW" .
