#!/bin/sh
# The README's vessel unmasking (issue 15 item 7; the paper's Fig. 2): the vessel channel with
# the brain tissue suppressed (`--tissues vessels,pathology`), on the phantom and on the MNI152
# T1 template (tools/perturbation/fetch-templates.sh, or /work/shared/data here).
# Usage: tools/figures/vessels.sh MNI152.nii.gz [MORPHRAY]
set -eu
mni=${1:?usage: $0 MNI152.nii.gz [morphray binary]}
morphray=${2:-morphray}
out=$(dirname "$0")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$morphray" phantom -o "$tmp/phantom.nii.gz"
for input in "$tmp/phantom.nii.gz" "$mni"; do
    case $input in
        "$mni") name=mni152 ;;
        *) name=phantom ;;
    esac
    "$morphray" render "$input" -o "$out/$name-vessels.png" --size 512x512 --view superior \
        --tissues vessels,pathology
done
