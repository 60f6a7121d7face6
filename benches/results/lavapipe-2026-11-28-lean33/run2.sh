#!/bin/bash
cd /tmp/lean33
for round in 1 2 3; do
 ./abl.sh ./morphray-old "A_old_shaded r$round" --shading on
 ./abl.sh ./morphray-n "N_exact_shaded r$round" --shading on --classification exact
 ./abl.sh ./morphray-n "N_table_shaded r$round" --shading on
 ./abl.sh ./morphray-old "A_old_unshaded r$round" --shading off
 ./abl.sh ./morphray-n "N_exact_unshaded r$round" --shading off --classification exact
 ./abl.sh ./morphray-n "N_table_unshaded r$round" --shading off
 ./abl.sh ./morphray-old "A_old_mip r$round" --mode mip
 ./abl.sh ./morphray-n "N_mip r$round" --mode mip
 SIZE=500x500 ./abl.sh ./morphray-old "A_old_shaded_500 r$round" --shading on
 SIZE=500x500 ./abl.sh ./morphray-n "N_table_shaded_500 r$round" --shading on
done
echo done
