#!/usr/bin/env bash
# Creates bench/.venv-ba with pycolmap (Ceres inside), pyceres and numpy/scipy.
# Idempotent: re-running only installs what is missing. Not used in CI.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
venv="${BA_VENV:-$(cd "$here/.." && pwd)/.venv-ba}"
py="${PYTHON:-python3}"
if [ ! -x "$venv/bin/python" ]; then
  "$py" -m venv "$venv"
fi
# The root .gitignore ignores /bench/.venv but not /bench/.venv-ba: a .gitignore of '*'
# inside the venv keeps git from ever seeing it (as Python >= 3.13's venv does itself).
[ -f "$venv/.gitignore" ] || printf '*\n' > "$venv/.gitignore"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
  "pycolmap>=3.10" "pyceres>=2.3" "numpy" "scipy"
"$venv/bin/python" - <<'PY'
import pycolmap, numpy
print("pycolmap", pycolmap.__version__, "numpy", numpy.__version__)
try:
    import pyceres
    print("pyceres", getattr(pyceres, "__version__", "?"))
except Exception as e:  # pyceres is optional
    print("pyceres unavailable:", e)
PY
echo "venv ready: $venv"
