"""Host threads around the dataset runner's computation: a reader one batch
ahead, a writer behind, and the JSON-lines report they feed."""

from __future__ import annotations

import concurrent.futures
import json
import queue
import threading
from pathlib import Path

from .plan import Batch

__all__ = ["read_ahead", "Report", "Writer"]


def read_ahead(plan: list[Batch], items, loader, prepare=None, readers: int = 2):
    """(batch, its meshes, prepared) one batch ahead, read on a thread; a mesh that
    fails to read comes as its exception.

    Arguments:
        plan: the batches, in order.
        items: (input path, output path) per item index.
        loader: the mesh reader (:func:`jaxmesh.load`).
        prepare: called as ``prepare(batch, meshes)`` on the reader thread too (the
            runner pads the batch there, overlapping the computation); None: no call.
        readers: the threads that read a batch's files (numpy's parsing and sorting
            release the GIL, so two readers use the core the computation leaves idle).

    Returns:
        A generator of (batch, [mesh or exception per item], what ``prepare`` returned or None)."""
    q: queue.Queue = queue.Queue(maxsize=1)

    def one(k):
        try:
            return loader(items[k][0])
        except (ValueError, OSError) as err:
            return err

    def read():
        try:
            with concurrent.futures.ThreadPoolExecutor(readers, thread_name_prefix="jaxmesh-read") as pool:
                for b in plan:
                    meshes = list(pool.map(one, b.items))
                    q.put((b, meshes, None if prepare is None else prepare(b, meshes)))
        except BaseException as err:    # anything else ends the stream in the consumer, not in a silent hang
            q.put(err)
            return
        q.put(None)

    threading.Thread(target=read, name="jaxmesh-read-ahead", daemon=True).start()
    while (got := q.get()) is not None:
        if isinstance(got, BaseException):
            raise got
        yield got


class Report:
    """The JSON-lines report, a line per input as soon as its fate is known (so an
    interrupted run keeps the lines of what it finished); None writes nothing."""

    def __init__(self, path):
        self._path, self._lock = path, threading.Lock()
        if path is None:
            return
        p = Path(path)
        if p.is_dir():
            raise ValueError(f"report {path}: is a directory; name the file to append to")
        if not p.parent.is_dir():
            raise ValueError(f"report {path}: directory {p.parent} does not exist")
        try:      # appending nothing creates the file: an unwritable report is refused before any work
            open(p, "a", encoding="utf-8").close()
        except OSError as err:
            raise ValueError(f"report {path}: cannot be written ({err.strerror or err})") from err

    def write(self, record: dict) -> None:
        if self._path is None:
            return
        try:
            with self._lock, open(self._path, "a", encoding="utf-8") as fh:
                fh.write(json.dumps(record) + "\n")
        except OSError as err:          # named: a full disk's error carries no file name
            raise OSError(err.errno, err.strerror or str(err), str(self._path)) from err


class Writer:
    """Writes results on a thread, behind the computation; a write that fails marks
    its record failed (skipped when the output appeared meanwhile, written by another
    run); each record goes to the report once written.  An error of the thread itself
    (the report cannot be appended to, a disk full) stops the report, not the writes,
    and :meth:`close` raises it."""

    def __init__(self, save, overwrite: bool, log: Report):
        self._q: queue.Queue = queue.Queue(maxsize=64)
        self._save, self._overwrite, self._log = save, overwrite, log
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=self._work, name="jaxmesh-write-behind", daemon=True)
        self._thread.start()

    def _work(self):
        while (job := self._q.get()) is not None:
            mesh, path, rec, check = job
            try:
                try:
                    if check is not None:
                        check()
                    self._save(mesh, path, overwrite=self._overwrite)
                except FileExistsError:     # another run wrote it meanwhile (the write never clobbers)
                    rec.update(status="skipped", reason="the output appeared while this run computed it")
                except (ValueError, OSError) as err:
                    rec.update(status="failed", error=f"{type(err).__name__}: {err}")
                if self.error is None:
                    self._log.write(rec)
            except Exception as err:      # kept for close(): the thread goes on draining, so put never blocks
                self.error = self.error or err

    def put(self, mesh, path, rec, check=None):
        """Save ``mesh`` to ``path`` (after ``check()``, which may add errors to ``rec``)."""
        self._q.put((mesh, path, rec, check))

    def close(self):
        """Wait for the pending writes; then raise the thread's own error, if it had one."""
        self._q.put(None)
        self._thread.join()
        err = self.error
        if isinstance(err, OSError):
            raise OSError(err.errno, f"{err.strerror or err}; the report stopped there (the outputs were written)",
                          err.filename) from err
        if err is not None:
            raise ValueError(f"the write-behind thread failed ({type(err).__name__}: {err}); the report stopped "
                             "there (the outputs were written)") from err
