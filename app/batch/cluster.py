"""Running rows on a dask.distributed cluster (``--scheduler``), with a bounded connection.

The scheduler address is user input and the peer may be anything: a port that accepts and
never speaks, a frame header announcing 8 EiB, a scheme Dask cannot use here. So:

- only ``tcp://HOST:PORT`` (or ``HOST:PORT``) and ``tls://HOST:PORT`` are accepted (and
  ``inproc://``, which reaches a scheduler in the same process only: a ``LocalCluster`` beside
  a call of :func:`ctdrill.app.batch.run.run_batch`); any other scheme (``ucx://``,
  ``ws://`` ...) is refused before anything is imported;
- ``tls://`` takes its certificates from Dask's configuration
  (``distributed.comm.tls.ca-file``, ``.client.cert``, ``.client.key``; e.g. the environment
  variables ``DASK_DISTRIBUTED__COMM__TLS__CA_FILE``, ``..._CLIENT__CERT``,
  ``..._CLIENT__KEY``); without a CA and a client certificate it is refused, naming them;
- the connection runs in a thread with a deadline (:data:`CONNECT_TIMEOUT_S`): whatever the
  peer does (silence, an oversized frame, garbage), ``connect`` ends within it with one
  :class:`BatchInputError` (exit 2), never a traceback or a hang.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

from ctdrill.app.batch.manifest import BatchInputError
from ctdrill.app.batch.task import RowOutcome, RowTask, one_line, run_row
from ctdrill.app.batch.workers import POLL_S, Interrupt

#: Schemes a scheduler address may use.
SCHEMES = ("tcp", "tls", "inproc")
#: The whole connection (Dask's handshake included) must succeed within this, s.
CONNECT_TIMEOUT_S = 8.0
#: A client that never connected is closed within this, s (in the background).
CLOSE_TIMEOUT_S = 2.0
#: Dask's TLS settings a ``tls://`` address needs (its configuration keys).
TLS_KEYS = ("distributed.comm.tls.ca-file", "distributed.comm.tls.client.cert")


def scheme_of(address: str) -> str:
    """The address's scheme (``tcp`` when it has none)."""
    return address.split("://", 1)[0].lower() if "://" in address else "tcp"


def _advice(address: str) -> str:
    return f"--scheduler {address}"


def connect(address: str) -> Any:
    """A dask.distributed ``Client`` of the scheduler at ``address``.

    Raises
    ------
    BatchInputError
        An unsupported scheme, ``tls://`` without certificates, dask.distributed missing, or
        no working Dask scheduler there within :data:`CONNECT_TIMEOUT_S` (refused, silent,
        oversized or malformed answers): one line naming the address and what to do.
    """
    scheme = scheme_of(address)
    if scheme not in SCHEMES:
        raise BatchInputError(
            f"{_advice(address)}: the scheme {scheme!r} is not supported; give "
            "tcp://HOST:PORT, or tls://HOST:PORT with certificates (docs/batch.md)"
        )
    try:
        from distributed import Client
        from distributed.security import Security
    except ImportError:
        raise BatchInputError(
            "--scheduler needs dask.distributed, which is not installed: "
            "pip install 'ctdrill[cluster]'"
        ) from None
    kwargs: dict[str, Any] = {}
    if scheme == "tls":
        security = Security()
        if not all(getattr(security, k, None) for k in ("tls_ca_file", "tls_client_cert")):
            raise BatchInputError(
                f"{_advice(address)}: tls:// needs certificates: set Dask's "
                f"{' and '.join(TLS_KEYS)} (and .client.key), e.g. "
                "DASK_DISTRIBUTED__COMM__TLS__CA_FILE=ca.pem "
                "DASK_DISTRIBUTED__COMM__TLS__CLIENT__CERT=me.pem "
                "DASK_DISTRIBUTED__COMM__TLS__CLIENT__KEY=me.key (docs/batch.md)"
            )
        kwargs["security"] = security
    got: dict[str, Any] = {}

    class _Client(Client):
        """A client whose failed construction is closed at once, quietly and in the
        background; Dask's own ``__del__`` would close it synchronously at exit, which on a
        peer that answered garbage waits twice the timeout (16 s) and then prints a
        traceback."""

        def __init__(self, *args: Any, **kw: Any) -> None:
            self._ctdrill_failed = False
            try:
                super().__init__(*args, **kw)
            except BaseException:
                self._ctdrill_failed = True
                closer = threading.Thread(target=_quiet_close, args=(self,), daemon=True)
                closer.start()
                raise

        def __del__(self) -> None:
            if not getattr(self, "_ctdrill_failed", True):
                super().__del__()

    def attempt() -> None:
        try:
            got["client"] = _Client(
                address, timeout=f"{CONNECT_TIMEOUT_S}s", set_as_default=False, **kwargs
            )
        except BaseException as exc:  # anything the peer provokes: reported, not raised
            got["error"] = one_line(f"{type(exc).__name__}: {exc}")[:300]

    worker = threading.Thread(target=attempt, name="ctdrill-scheduler-connect", daemon=True)
    worker.start()
    worker.join(CONNECT_TIMEOUT_S)
    if "client" in got:
        return got["client"]
    if worker.is_alive():
        why = f"no answer as a Dask scheduler within {CONNECT_TIMEOUT_S:g} s"
    else:
        why = str(got.get("error"))
    raise BatchInputError(
        f"{_advice(address)}: cannot connect ({why}); start one with 'dask scheduler' and give "
        "its address (tcp://HOST:8786)"
    )


def _quiet_close(client: Any) -> None:
    """Close a client that never connected, briefly, whatever it raises."""
    with contextlib.suppress(BaseException):
        client.close(timeout=CLOSE_TIMEOUT_S)


def run_dask(
    tasks: Sequence[RowTask],
    client: Any,
    on_done: Callable[[RowOutcome], None],
    stop: Interrupt,
) -> None:
    """Run the tasks on the dask.distributed cluster of ``client`` (closed at the end) until
    Ctrl-C, which cancels the rows not finished (they are reported "not run").

    Workers write the rows' folders themselves: every path must mean the same on them as
    here (a shared file system mounted at the same place; ``docs/batch.md``).
    """
    from distributed import as_completed

    with client:
        futures = client.map(run_row, list(tasks), pure=False)
        row_of = {f.key: t for f, t in zip(futures, tasks, strict=True)}
        done = as_completed(futures, loop=client.loop)
        while not done.is_empty():
            if stop.stopping:
                client.cancel([f for f in futures if not f.done()])
                break
            batch = done.next_batch(block=False)
            if not batch:
                time.sleep(POLL_S)
            for fut in batch:
                task = row_of[fut.key]
                try:
                    outcome = fut.result()
                except Exception as exc:  # KilledWorker, a lost connection: the row failed
                    outcome = RowOutcome(
                        row=task.row,
                        status=one_line(
                            f"error: the cluster could not run this row: {type(exc).__name__}: "
                            f"{exc}"
                        ),
                        seconds=0.0,
                    )
                on_done(outcome)
