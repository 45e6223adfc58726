#!/usr/bin/env bash
# Installs what the Python module and its tests need into the `python3` on PATH
# (or $PYTHON): nanobind and scikit-build-core (build), NumPy and pytest (tests), gsd (the GSD
# tests; optional), mpi4py where MPI is installed (the rpyfmm.mpi tests).
# matplotlib is optional (examples/python). Called by scripts/install-deps.sh.
# Idempotent: nothing is downloaded when everything imports already.
set -euo pipefail
PY="${PYTHON:-python3}"

# Debian's own python3 is "externally managed" (PEP 668): pip needs --break-system-packages
# there (the packages go to /usr/local, apart from Debian's). A venv or pyenv python does not.
pip_install() {
  if ! "$PY" -m pip install --quiet "$@" 2>/tmp/rpyfmm-pip.err; then
    if grep -q "externally-managed-environment" /tmp/rpyfmm-pip.err; then
      "$PY" -m pip install --quiet --break-system-packages "$@"
    else
      cat /tmp/rpyfmm-pip.err >&2
      return 1
    fi
  fi
}

if ! "$PY" - <<'PYEOF' 2>/dev/null; then
import importlib.metadata as md
import nanobind, numpy, pytest, scikit_build_core  # noqa: F401
assert int(md.version("nanobind").split(".")[0]) >= 2
PYEOF
  pip_install "nanobind>=2.0" "scikit-build-core>=0.10" "numpy>=1.22" "pytest>=7"
fi
# gsd reads the GSD trajectories in tests/python/test_gsd.py; optional: those tests skip without it.
if ! "$PY" -c "import gsd.hoomd" 2>/dev/null; then
  pip_install gsd || echo "install-python-deps: gsd not installed; the Python GSD tests will skip" >&2
fi
# mpi4py runs the rpyfmm.mpi tests (tests/mpi/CMakeLists.txt registers them only where this
# interpreter imports it). Debian's python3-mpi4py serves Debian's python3 only; another
# interpreter (pyenv, a venv) gets PyPI's, which loads the system Open MPI (libopenmpi-dev).
if command -v mpiexec >/dev/null && ! "$PY" -c "import mpi4py" 2>/dev/null; then
  pip_install mpi4py || echo "install-python-deps: mpi4py not installed; the rpyfmm.mpi Python tests are not registered" >&2
fi
