#!/usr/bin/env bash
# One-time (and idempotent) set-up of the project:
#   1. .venv/ at the repository root: requirements.txt at the versions pinned in requirements.lock
#      (ROS 2 Jazzy from the ros-jazzy-* wheels, numpy, scipy, OpenCV, scikit-learn, mcap, colcon, pytest ...)
#   2. the src/ packages importable from that venv (a .pth file, like an editable install)
#   3. `colcon build --symlink-install` of ros_ws/ (sources: ../src)
# Each step is skipped when its inputs did not change, so a second run takes about a second.
# Safe to run from several shells at once (flock).
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"

exec 9>"$ROOT/.setup.lock"
flock 9

PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  echo "[setup] creating .venv with $($PY --version)"
  "$PY" -m venv .venv
fi

want=$(cat requirements.txt requirements.lock | sha256sum | cut -d' ' -f1)
if [ "$(cat .venv/.requirements.sha 2>/dev/null || true)" != "$want" ]; then
  echo "[setup] installing pinned packages (requirements.txt, versions from requirements.lock)"
  .venv/bin/python -m pip install -q --disable-pip-version-check -r requirements.txt -c requirements.lock \
    > .venv/pip-install.log 2>&1 || { grep -v '^WARNING: Location' .venv/pip-install.log; echo "[setup] pip install FAILED"; exit 1; }
  echo "$want" > .venv/.requirements.sha
fi

# The src packages on the venv's path (absolute paths of this checkout).
site=$(.venv/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
pth="$site/catheter_ws_src.pth"
tmp=$(mktemp)
for d in src/*/; do
  [ -f "$d/package.xml" ] && echo "$ROOT/${d%/}" >> "$tmp"
done
if ! cmp -s "$tmp" "$pth" 2>/dev/null; then cp "$tmp" "$pth"; fi
rm -f "$tmp"

# colcon build when packaging files changed (symlink-install: source edits need no rebuild).
stamp_now=$(find src -maxdepth 3 \( -name package.xml -o -name setup.py -o -name setup.cfg -o -path '*/resource/*' \) \
            -type f -print0 | sort -z | xargs -0 sha256sum | sha256sum | cut -d' ' -f1)
if [ "$(cat ros_ws/.build.sha 2>/dev/null || true)" != "$stamp_now" ] || [ ! -d ros_ws/install ]; then
  echo "[setup] colcon build (ros_ws)"
  (
    cd ros_ws
    export VIRTUAL_ENV="$ROOT/.venv" PATH="$ROOT/.venv/bin:$PATH" AMENT_PREFIX_PATH="$ROOT/.venv"
    rm -rf build install; mkdir -p log
    colcon --log-base log build --symlink-install --event-handlers console_cohesion- summary- \
      > log/last_build.txt 2>&1 || { mkdir -p log; cat log/last_build.txt; exit 1; }
  ) || { echo "[setup] colcon build FAILED"; exit 1; }
  echo "$stamp_now" > ros_ws/.build.sha
fi
echo "[setup] ready: .venv ($(.venv/bin/python --version)), ros_ws/install"
