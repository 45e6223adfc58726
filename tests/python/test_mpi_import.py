"""`import rpyfmm.mpi` where it cannot work: a module built without MPI, or no mpi4py.

Both cases are simulated in this process (the submodule hidden, mpi4py made unimportable), so
they run whatever the build; nothing here imports mpi4py or initializes MPI. The operators
themselves are tested across ranks in tests/python/mpi (docs/mpi.md, "Python (mpi4py)").
"""

from __future__ import annotations

import importlib
import sys

import pytest

from rpyfmm import _rpyfmm


@pytest.fixture
def fresh_import(monkeypatch: pytest.MonkeyPatch):
    """Imports rpyfmm.mpi anew, restoring sys.modules afterwards."""
    monkeypatch.delitem(sys.modules, "rpyfmm.mpi", raising=False)
    yield lambda: importlib.import_module("rpyfmm.mpi")
    sys.modules.pop("rpyfmm.mpi", None)


def test_built_without_mpi_says_so(monkeypatch: pytest.MonkeyPatch, fresh_import) -> None:
    monkeypatch.delattr(_rpyfmm, "mpi", raising=False)
    with pytest.raises(ImportError, match="built without MPI.*RPYFMM_USE_MPI=ON"):
        fresh_import()


def test_without_mpi4py_names_it(monkeypatch: pytest.MonkeyPatch, fresh_import) -> None:
    if not hasattr(_rpyfmm, "mpi"):
        pytest.skip("this rpyfmm module was built without MPI")
    monkeypatch.setitem(sys.modules, "mpi4py", None)  # `import mpi4py` raises ImportError
    with pytest.raises(ImportError, match="needs mpi4py.*python3-mpi4py"):
        fresh_import()
