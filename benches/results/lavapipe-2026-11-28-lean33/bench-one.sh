#!/bin/bash
# usage: abl.sh BIN LABEL [extra args...] ; prints one line: label, ms, samples
B=$1; L=$2; shift 2
D=/work/shared/data/mni152_t1_2009a.nii.gz
out=$($B bench $D --size ${SIZE:-320x180} --frames 20 --repeat 1 --trials 0 "$@" 2>&1)
line=$(echo "$out" | grep '^raymarch:')
ms=$(echo "$line" | sed -E 's/raymarch: ([0-9.]+) ms.*/\1/')
ms_samples=$(echo "$line" | sed -E 's/.*; ([0-9.]+) M samples\/frame \(([0-9.]+) M classified.*/\1 \2/')
echo "$L $ms $ms_samples $(echo "$ms $ms_samples" | awk '{printf "%.1f ns/sample", $1*1e6/($2*1e6)}')"
