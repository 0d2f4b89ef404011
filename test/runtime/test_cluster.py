"""The local Dask cluster of sweeps and batches: quiet beside another one."""

from __future__ import annotations

import socket
import warnings

from ins_fusion.runtime.cluster import cluster, completed, submit_each


def _twice(x: int) -> int:
    return 2 * x


def test_a_local_cluster_beside_another_starts_quietly_and_runs_its_tasks(capfd) -> None:
    # Another cluster's HTTP server (or anything else) on Dask's default port 8787.
    with socket.socket() as taken:
        taken.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            taken.bind(("", 8787))
            taken.listen()
        except OSError:
            pass  # already taken by someone else: the same situation
        with warnings.catch_warnings(record=True) as warned:
            warnings.simplefilter("always")
            with cluster(None, 1, 2) as client:
                futures = submit_each(client, _twice, {"a": (1,), "b": (2,)})
                results = {key: (value, error) for key, value, error in completed(futures)}
    assert not [str(w.message) for w in warned if "in use" in str(w.message)]
    assert results == {"a": (2, None), "b": (4, None)}
    err = capfd.readouterr().err
    assert "already in use" not in err and "Traceback" not in err, err
