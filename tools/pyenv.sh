#!/usr/bin/env bash
# The Python environment of the tests and tools (DICOM test series and dcm2niix, the Python
# package's build and tests, the batch workflow), idempotently:
#   - a venv under the user's cache directory (outside any clone, so a second CI run reuses it);
#   - the packages pinned in tools/requirements-test.txt, reinstalled only when that file changes.
# Prints nothing but progress; the venv's path is ${MORPHRAY_PYENV:-~/.cache/morphray/pyenv}.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
env_dir="${MORPHRAY_PYENV:-${XDG_CACHE_HOME:-$HOME/.cache}/morphray/pyenv}"
req="$here/requirements-test.txt"
stamp="$env_dir/.requirements.sha256"
want="$(sha256sum "$req" | cut -d' ' -f1)"
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && [ -x "$env_dir/bin/python" ]; then
    echo "pyenv: $env_dir is up to date"
    exit 0
fi
# Debian's python3 (/usr/bin/python3 has the venv module once python3-venv is installed).
python=/usr/bin/python3
[ -x "$python" ] || python="$(command -v python3)"
echo "pyenv: creating $env_dir from $req"
"$python" -m venv "$env_dir"
"$env_dir/bin/python" -m pip install -q --upgrade pip
"$env_dir/bin/python" -m pip install -q -r "$req"
echo "$want" > "$stamp"
echo "pyenv: done"
