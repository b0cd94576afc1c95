#!/usr/bin/env bash
# One-time (and idempotent) set-up of the project:
#   1. .venv/ at the repository root: requirements.txt at the versions pinned in requirements.lock
#      (ROS 2 Jazzy from the ros-jazzy-* wheels, numpy, scipy, OpenCV, scikit-learn, mcap, colcon, pytest ...)
#   2. the wheels' exported CMake files pointed at this Python (scripts/fix_ros_wheel_paths.py,
#      idempotent; needed to build the interface package, see docs/BUILD.md)
#   3. the src/ Python packages importable from that venv (a .pth file, like an editable install)
#   4. `colcon build --symlink-install` of ros_ws/ (sources: ../src): catheter_interfaces
#      (ament_cmake + rosidl: C code generated and compiled, ~10 s) first, then the
#      ament_python packages. A package that fails to build fails the set-up with its log.
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

# The ros-jazzy-* wheels name their build container's Python in their CMake exports.
.venv/bin/python scripts/fix_ros_wheel_paths.py "$ROOT/.venv" || { echo "[setup] fixing the ROS wheels' CMake paths FAILED"; exit 1; }

# The src Python packages on the venv's path (absolute paths of this checkout).
site=$(.venv/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
pth="$site/catheter_ws_src.pth"
tmp=$(mktemp)
for d in src/*/; do
  [ -f "$d/package.xml" ] && [ -f "$d/setup.py" ] && echo "$ROOT/${d%/}" >> "$tmp"
done
if ! cmp -s "$tmp" "$pth" 2>/dev/null; then cp "$tmp" "$pth"; fi
rm -f "$tmp"

# colcon build when packaging files, interface definitions or installed data files changed
# (symlink-install: edits of Python sources and of existing data files need no rebuild).
stamp_now=$( (find src -maxdepth 3 \( -name package.xml -o -name setup.py -o -name setup.cfg \
               -o -name CMakeLists.txt -o -path '*/resource/*' -o -path '*/msg/*.msg' \) -type f -print0 \
               | sort -z | xargs -0 sha256sum; \
             find src -maxdepth 4 \( -path '*/config/*' -o -path '*/launch/*' -o -path '*/models/*' \) \
               -type f | sort) | sha256sum | cut -d' ' -f1)
if [ "$(cat ros_ws/.build.sha 2>/dev/null || true)" != "$stamp_now" ] || [ ! -d ros_ws/install ]; then
  echo "[setup] colcon build (ros_ws)"
  (
    cd ros_ws
    export VIRTUAL_ENV="$ROOT/.venv" PATH="$ROOT/.venv/bin:$PATH" AMENT_PREFIX_PATH="$ROOT/.venv"
    rm -rf build install; mkdir -p log
    colcon --log-base log build --symlink-install --event-handlers console_cohesion+ summary+ \
      --cmake-args -DBUILD_TESTING=OFF \
      > log/last_build.txt 2>&1 || { tail -n 80 log/last_build.txt; exit 1; }
    # the typed messages must import from the built workspace (what tests, nodes and tools do)
    ( set +u; . install/setup.bash; python -c 'from catheter_interfaces.msg import ImpedanceModel' ) \
      || { echo "[setup] catheter_interfaces does not import from ros_ws/install"; exit 1; }
  ) || { echo "[setup] colcon build FAILED (full log: ros_ws/log/last_build.txt)"; exit 1; }
  echo "$stamp_now" > ros_ws/.build.sha
fi
echo "[setup] ready: .venv ($(.venv/bin/python --version)), ros_ws/install"
