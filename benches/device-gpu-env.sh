# Sourced by the benches/device-*.sh scripts that carry the binary in .gpu and the Vulkan loader
# packages in .gl (run(..., carry=[".gl", ".gpu"])): unpacks the loader, points it at NVIDIA's
# ICD, and sets
#   M    the morphray binary (.gpu/morphray)
#   OUT  what comes back from the device call (the tool's $OUT)
#   V    a scratch folder for volumes
for f in .gl/lib{vulkan1,egl1,glvnd0,opengl0,gl1,glx0,gles2}_*.deb; do dpkg -x "$f" /; done
ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
M=.gpu/morphray
OUT=${OUT:-/tmp/morphray-out}
mkdir -p "$OUT"
V=$(mktemp -d)
