# Sourced by the benches/device-*.sh scripts that take the binary and MNI152 from .sv: unpacks
# the Vulkan loader packages (.glmin), points the loader at NVIDIA's ICD, and sets
#   OUT  what comes back from the device call (the tool's $OUT)
#   RAW  a scratch folder for every raw output (the caller tars it into $OUT: few files return)
#   V    a scratch folder for volumes
#   M    the morphray binary, unpacked from .sv/morphray.xz
# and, when .sv/mni.nii.xz exists, $V/mni152.nii.gz (gzip level 6, one member, as distributed).
for f in .glmin/lib{vulkan1,egl1,glvnd0,opengl0,gl1,glx0,gles2}_*.deb; do dpkg -x "$f" /; done
ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
OUT=${OUT:-/tmp/morphray-out}
RAW=$(mktemp -d)
V=$(mktemp -d)
mkdir -p "$OUT"
python3 -c 'import lzma,shutil,sys; shutil.copyfileobj(lzma.open(sys.argv[1]), open(sys.argv[2], "wb"))' \
    .sv/morphray.xz /tmp/morphray && chmod +x /tmp/morphray
M=/tmp/morphray
if [ -f .sv/mni.nii.xz ]; then
    python3 -c 'import lzma,gzip,shutil,sys; shutil.copyfileobj(lzma.open(sys.argv[1]), gzip.open(sys.argv[2], "wb", 6))' \
        .sv/mni.nii.xz "$V/mni152.nii.gz"
fi
