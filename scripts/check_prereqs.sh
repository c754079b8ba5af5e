#!/usr/bin/env bash
# Stops `make setup` at once, with one line, when the machine lacks what the build needs.
# Usage: check_prereqs.sh PYTHON   (the interpreter that will create .venv)
python=${1:-python3.11}
hint='on Debian 12: sudo apt-get install python3.11 python3.11-venv python3.11-dev gcc g++ cmake make'
fail() { echo "setup: missing $1 ($hint)" >&2; exit 1; }
command -v "$python" >/dev/null 2>&1 || fail "Python 3.11 (no '$python' on PATH)"
version=$("$python" -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null)
[ "$version" = 3.11 ] || fail "Python 3.11 ('$python' is Python ${version:-unknown}; the ROS 2 Jazzy wheels are cp311)"
"$python" -c 'import venv, ensurepip' >/dev/null 2>&1 || fail "the Python 3.11 venv module"
inc=$("$python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
[ -f "$inc/Python.h" ] || fail "the Python 3.11 headers (no $inc/Python.h)"
command -v gcc >/dev/null 2>&1 || fail "gcc"
command -v g++ >/dev/null 2>&1 || fail "g++"
command -v cmake >/dev/null 2>&1 || fail "cmake"
exit 0
