"""What rpyfmm.mpi tests share: the world communicator, uneven shares of n items with rank 0
empty, and a call that must raise on every rank (imported by name: pytest puts this folder on
sys.path, as it has no __init__.py)."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

COMM = MPI.COMM_WORLD
RANK, SIZE = COMM.Get_rank(), COMM.Get_size()


def share_without_first(n: int) -> slice:
    """This rank's slice of n items: uneven contiguous shares (rank r gets about r parts), rank 0
    none where there are several ranks, everything on one rank."""
    weights = np.arange(SIZE, dtype=float) if SIZE > 1 else np.ones(1)
    bounds = np.rint(np.concatenate([[0.0], np.cumsum(weights)]) / weights.sum() * n).astype(int)
    return slice(bounds[RANK], bounds[RANK + 1])


def raised_on_every_rank(call, error=None) -> list[str]:
    """Runs `call` (collective), which must raise `error` (rpyfmm.Error by default) here; returns
    every rank's message (collective)."""
    import rpyfmm

    with pytest.raises(error or rpyfmm.Error) as caught:
        call()
    return COMM.allgather(str(caught.value))
