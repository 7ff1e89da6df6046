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
# Byte-compile what changed since the last set-up: the dependencies pip just installed and
# dampnet's own modules. These machines set PYTHONDONTWRITEBYTECODE=1, so no process caches its
# .pyc files: without this every process compiled every module it imported, every time (tried:
# the suite 300 s slower a worker), and an editable install's own package is never compiled by
# pip (0.6 s more for each process importing the training and the diagnosis). compileall may use
# both cores where pip compiles on one (`pip install [--no-compile] -r` this venv's `pip freeze` into
# a fresh venv, a loaded machine: 83 s with pip's compile, 38 s without + 48 s of compileall; a fresh
# clone's whole set-up took 123-126 s either way); the stamp keeps a set-up with nothing new at one
# `find` (0.5 s).
compiled=.venv/.dampnet-compiled
site="$(python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
newer=()
[ -f "$compiled" ] && newer=(-newer "$compiled")
touch "$compiled.next"  # (before the search: a file changed during it is compiled next time)
find "$site" python/dampnet -name '*.py' ${newer[@]+"${newer[@]}"} -print \
  | python -m compileall -q -j 0 -i - >/dev/null 2>&1 || true
mv "$compiled.next" "$compiled"

if (($#)); then
  exec "$@"
fi
