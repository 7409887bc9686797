#!/usr/bin/env bash
# One entry point for a fresh machine: creates .venv, installs what is missing, then runs
#   ./agv.sh demo [args]   the closed-loop demonstration (see README)
#   ./agv.sh test [args]   the whole test suite (what CI runs)
#   ./agv.sh env           only the set-up; prints the venv's python
set -euo pipefail
cd "$(dirname "$0")"
VENV=${AGV_VENV:-.venv}

pick_python() {
  for py in python3.11 python3; do
    if command -v "$py" >/dev/null 2>&1 &&
       "$py" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then
      echo "$py"; return
    fi
  done
  echo "agv.sh: Python 3.11 is required (the ROS 2 Jazzy wheels on PyPI are cp311)" >&2
  exit 2
}

ensure_venv() {
  if [[ ! -x "$VENV/bin/python" ]]; then
    "$(pick_python)" -m venv "$VENV"
  fi
  local stamp="$VENV/.agv_nodes-installed" want
  want=$(cat requirements.txt setup.py setup.cfg package.xml agv_nodes/*/_*.c | sha256sum | cut -d' ' -f1)
  if [[ ! -f "$stamp" || "$(cat "$stamp")" != "$want" ]]; then
    echo "agv.sh: installing requirements into $VENV ..." >&2
    "$VENV/bin/python" -m pip install -q --upgrade pip
    "$VENV/bin/python" -m pip install -q -r requirements.txt
    "$VENV/bin/python" -m pip install -q --no-deps -e .
    echo "$want" > "$stamp"
  fi
  # Bytecode for the package's modules, kept up to date here: where PYTHONDONTWRITEBYTECODE is
  # set, every node process would otherwise compile them again (about 0.1 s of CPU each).
  "$VENV/bin/python" -m compileall -q agv_nodes >/dev/null
}

# The MQTT tests run against mosquitto, the broker plants use (Debian's package): installed here
# when it is missing and this is root with apt-get (as on CI), else named as what is missing.
ensure_broker() {
  if command -v mosquitto >/dev/null 2>&1 || [[ -x /usr/sbin/mosquitto ]]; then
    return
  fi
  if [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null 2>&1; then
    echo "agv.sh: installing mosquitto (Debian package) for the MQTT tests ..." >&2
    apt-get update -qq >/dev/null
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq mosquitto >/dev/null
  else
    echo "agv.sh: mosquitto is not installed and this is not root: install the package" \
      "mosquitto (the MQTT tests need it)" >&2
  fi
}

cmd=${1:-help}
[[ $# -gt 0 ]] && shift
case "$cmd" in
  test)
    ensure_venv
    ensure_broker
    # One process unless AGV_TEST_WORKERS=N: then N pytest-xdist workers, the tests over DDS one
    # at a time in a lane of their own, the rest beside them at nice 19 (test/conftest.py). On
    # two cores the lanes are no faster than one process (bench/results/test_suite.md).
    exec "$VENV/bin/python" -m pytest -n "${AGV_TEST_WORKERS:-0}" --dist loadgroup \
      --no-loadscope-reorder "$@"
    ;;
  demo)
    ensure_venv
    exec "$VENV/bin/python" -m agv_nodes.demo "$@"
    ;;
  env)
    ensure_venv
    echo "$VENV/bin/python"
    ;;
  *)
    sed -n '2,6p' "$0" | sed 's/^# \{0,1\}//'
    exit 2
    ;;
esac
