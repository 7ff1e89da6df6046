#!/usr/bin/env bash
# Usage: bash python/env.sh COMMAND [ARGS...]   e.g. `bash python/env.sh dampnet demo`
# Sets up everything dampnet needs on a fresh machine, idempotently, then runs
# COMMAND inside the environment:
# the Debian packages of python/debian-packages.txt, a virtual environment in
# .venv, the Python dependencies (torch pinned to the local CPU build), and
# the C++ core built into the package (editable install, incremental rebuild).
set -euo pipefail
DN_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$DN_ROOT"

dn_log() { printf '[dampnet setup] %s\n' "$*" >&2; }

# Debian packages: every one named in python/debian-packages.txt (one a line, with what needs
# it), each checked with dpkg-query and installed when missing. A package that could not be
# installed is named here, and every test that needs it fails naming it again.
dn_apt_list="$DN_ROOT/python/debian-packages.txt"
dn_installed() { [ "$(dpkg-query -W -f='${db:Status-Status}' "$1" 2>/dev/null)" = installed ]; }
need_apt=()
while read -r pkg _; do
  dn_installed "$pkg" || need_apt+=("$pkg")
done < <(sed -e 's/#.*//' -e '/^[[:space:]]*$/d' "$dn_apt_list")
if ((${#need_apt[@]})); then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    dn_log "installing Debian packages: ${need_apt[*]}"
    apt-get update -qq >/dev/null 2>&1 || dn_log "warning: apt-get update failed"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${need_apt[@]}" \
      >/dev/null 2>&1 || true
  fi
  still=()
  for pkg in "${need_apt[@]}"; do dn_installed "$pkg" || still+=("$pkg"); done
  if ((${#still[@]})); then
    dn_log "warning: Debian packages not installed (not root, no apt-get, or the install failed): ${still[*]}"
    dn_log "         the tests that need them will fail naming them; install with: apt-get install ${still[*]}"
  fi
fi

PY="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
  dn_log "creating virtual environment in .venv"
  "$PY" -m venv .venv
fi
# shellcheck disable=SC1091
source .venv/bin/activate

# Build tools first (the editable install builds without isolation so that
# CMake's build/ directory is reused), then dampnet with its extras; torch is
# pinned in pyproject.toml to the local CPU build.
stamp=.venv/.dampnet-build-tools
if [ ! -f "$stamp" ]; then
  dn_log "installing build tools into .venv"
  python -m pip install -q --upgrade pip >/dev/null 2>&1
  python -m pip install -q scikit-build-core pybind11 cmake ninja 2> >(grep -v "^WARNING: Location" >&2)
  touch "$stamp"
fi
dn_log "building the C++ core and installing dampnet with its dependencies (first run: a few minutes)"
# pip's "Location ... is ignored" lines are about this machine's optional local mirrors: noise.
python -m pip install -q --no-compile --no-build-isolation -e ".[train,test,bench,lab]" \
  2> >(grep -v "^WARNING: Location" >&2)
# Bytecode: these machines set PYTHONDONTWRITEBYTECODE=1, under which no process writes the .pyc
# files it compiles, so every process compiled every module it imported, every time (tried: the
# suite 300 s slower a worker; 0.6 s more for each process importing the training and the
# diagnosis). The commands run here write theirs, as Python does by default: a module is compiled
# the first time any process imports it, and only what something imports (importing every library
# the suite uses loads about 2,400 of site-packages' 12,900 files; compiling all of them ahead, as
# this script did before, took 64 s of CPU, 26-48 s of a fresh set-up). Hence pip's --no-compile.
unset PYTHONDONTWRITEBYTECODE

if (($#)); then
  exec "$@"
fi
