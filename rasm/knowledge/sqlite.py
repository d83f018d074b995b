"""The Storage Manager's SQLite engine: one file, WAL journal, one transaction per flush.

Durability choice: ``journal_mode=WAL`` with ``synchronous=NORMAL`` by default. A transaction
is in the WAL file when ``update_persistency`` returns, so a killed process (``kill -9``, an
out-of-memory kill, a crash) loses nothing that was persisted; only an operating-system crash
or a power cut may roll back the last transactions since the WAL was last synced, and never
corrupts the file. ``durable=True`` selects ``synchronous=FULL``: one fsync per flush, so a power
cut loses nothing persisted either, at the price of that fsync (milliseconds on SD cards).

One writer per file: a ``PATH.lock`` file beside it is locked (``flock``) while the storage is
open, so a second ``rasm run`` of the same application fails at once instead of mixing writes.
Other processes may read the file (``sqlite3 PATH``) at any time.
"""

from __future__ import annotations

import logging
import os
import sqlite3
import sys
import threading
from collections import deque
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rasm.errors import KnowledgeError
from rasm.knowledge.base import KnowledgeBase, Sample
from rasm.knowledge.storage import Storage
from rasm.knowledge.values import (
    Declaration,
    decode,
    encode,
    infer_type,
    make_check,
)
from rasm.losses import describe_error

_log = logging.getLogger("rasm.knowledge")

SCHEMA_VERSION = 2
DEFAULT_KEEP = 10_000
"""Samples kept on disk per key unless ``keep`` says otherwise."""

# One row per key per flush: a flush writes a handful of rows, not one per sample (a simulated
# hour of the Hotbox registers 230k values), and each row's times and values are one JSON text.
_SCHEMA = """
CREATE TABLE IF NOT EXISTS declarations (
    key TEXT PRIMARY KEY,
    type TEXT NOT NULL,
    history INTEGER NOT NULL,
    minimum TEXT,            -- JSON number or NULL (TEXT: an int bound keeps every digit)
    maximum TEXT
);
CREATE TABLE IF NOT EXISTS batches (
    seq INTEGER PRIMARY KEY, -- flush order: orders the batches of a key even at equal times
    key TEXT NOT NULL,
    count INTEGER NOT NULL,  -- samples in the batch
    last REAL NOT NULL,      -- time of its newest sample
    type TEXT NOT NULL,
    times TEXT NOT NULL,     -- JSON array of the times, oldest first
    "values" TEXT NOT NULL   -- JSON array of the values (Python's dialect: NaN and Infinity)
);
CREATE INDEX IF NOT EXISTS batches_by_key ON batches (key, seq);
"""

_BEFORE_ALL = -sys.float_info.max


class SqliteStorage(Storage):
    """Knowledge persisted in the SQLite file ``path``: the newest ``keep`` samples of each key
    (and at most a sixteenth more, pruned back to ``keep`` when there are).

    ``register_knowledge_update`` only buffers (at most ``keep`` per key: older ones would be
    pruned anyway); ``update_persistency`` writes the buffer in one transaction and prunes.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        keep: int = DEFAULT_KEEP,
        durable: bool = False,
        fresh: bool = False,
    ) -> None:
        super().__init__()
        if isinstance(keep, bool) or not isinstance(keep, int) or keep < 1:
            raise KnowledgeError(f"keep must be a whole number >= 1, got {keep!r}")
        self.path = Path(path)
        self.keep = keep
        self.durable = durable
        # Lock order: _db_lock, then _buf_lock or the knowledge base's lock, never both of the
        # last two at once. Registrations take only _buf_lock, so a flush never blocks them.
        self._db_lock = threading.Lock()
        self._buf_lock = threading.Lock()
        self._pending: dict[str, deque[Sample]] = {}
        self._known: dict[str, Declaration] = {}  # on disk or waiting to be written
        self._last: dict[str, float] = {}  # newest time taken from the buffer, per key
        self._written: dict[str, Declaration] = {}  # as on disk
        self._counts: dict[str, int] = {}  # samples on disk per key (we are the only writer)
        self._lock_fd = _take_lock(self.path)
        try:
            if fresh:  # only once the lock is ours: never under another run's open file
                for suffix in ("", "-wal", "-shm"):
                    Path(f"{self.path}{suffix}").unlink(missing_ok=True)
            self._db: sqlite3.Connection | None = self._connect()
        except BaseException:
            _release_lock(self._lock_fd)
            raise

    def __repr__(self) -> str:
        return f"SqliteStorage({str(self.path)!r}, keep={self.keep})"

    @property
    def location(self) -> str:
        return str(self.path)

    @property
    def pending(self) -> int:
        with self._buf_lock:
            return sum(len(queue) for queue in self._pending.values())

    # -- opening --------------------------------------------------------------------------------

    def _connect(self) -> sqlite3.Connection:
        try:
            # isolation_level=None: we issue BEGIN/COMMIT ourselves, one transaction per flush
            db = sqlite3.connect(str(self.path), check_same_thread=False, isolation_level=None)
        except sqlite3.Error as exc:
            raise KnowledgeError(
                f"opening the knowledge store {self.path} failed: {describe_error(exc)}"
            ) from exc
        try:
            version = db.execute("PRAGMA user_version").fetchone()[0]
            tables = {row[0] for row in db.execute("SELECT name FROM sqlite_master")}
            known_version = version in (1, SCHEMA_VERSION) or (version == 0 and not tables)
            if not known_version:
                raise KnowledgeError(
                    f"{self.path} is not a rasm knowledge file of schema {SCHEMA_VERSION} "
                    f"(user_version {version}): point sqlite: at another file"
                )
            mode = db.execute("PRAGMA journal_mode=WAL").fetchone()[0]
            if str(mode).lower() != "wal":
                _log.warning("%s: journal mode is %s, not WAL (file system?)", self.path, mode)
            db.execute(f"PRAGMA synchronous={'FULL' if self.durable else 'NORMAL'}")
            # one transaction: a kill half-way never leaves tables without the version mark
            db.execute("BEGIN IMMEDIATE")
            for statement in _SCHEMA.split(";"):
                db.execute(statement)
            if version == 1:
                _convert_schema_1(db, self.path)
            db.execute(f"PRAGMA user_version={SCHEMA_VERSION}")
            db.execute("COMMIT")
            for key, type_, history, lo, hi in db.execute(
                "SELECT key, type, history, minimum, maximum FROM declarations"
            ):
                decl = _declaration(self.path, key, type_, history, lo, hi)
                self._written[key] = self._known[key] = decl
            for key, count, last in db.execute(
                "SELECT key, SUM(count), MAX(last) FROM batches GROUP BY key"
            ):
                self._counts[key] = count
                self._last[key] = last
        except sqlite3.DatabaseError as exc:
            db.close()
            raise KnowledgeError(f"{self.path} is not a rasm knowledge file: {exc}") from exc
        except BaseException:
            db.close()
            raise
        return db

    # -- buffering ------------------------------------------------------------------------------

    def buffer(self, key: str, sample: Sample) -> None:
        """Buffer a sample a knowledge base already accepted (see :meth:`Storage.buffer`)."""
        self.buffer_all([(key, sample)])

    def buffer_all(self, samples: list[tuple[str, Sample]]) -> None:
        """:meth:`buffer` each pair, under one acquisition of the buffer's lock."""
        with self._buf_lock:
            for key, sample in samples:
                queue = self._pending.get(key)
                if queue is None:
                    queue = self._pending[key] = deque(maxlen=self.keep)
                queue.append(sample)

    def register_knowledge_update(self, key: str, sample: Sample) -> None:
        """Buffer one sample of ``key``, checked against its declaration (the attached knowledge
        base's, else the stored one, else inferred from this value) and its last time.

        An attached knowledge base, or the Storage Manager, buffers what a knowledge base
        accepted through the cheaper :meth:`buffer`.
        """
        if self._db is None:
            raise KnowledgeError(f"knowledge file {self.path} is closed")
        time, value = sample
        kb = self._kb
        decl = kb.declaration(key) if kb is not None else None
        with self._buf_lock:
            decl = decl or self._known.get(key) or Declaration(key, infer_type(value))
            value = make_check(decl)(value)
            if isinstance(time, bool) or not isinstance(time, int | float):
                raise KnowledgeError(f"knowledge {key!r}: time must be a number, got {time!r}")
            time = float(time)
            pending = self._pending.get(key)
            last = pending[-1].time if pending else self._last.get(key, _BEFORE_ALL)
            if not last <= time < float("inf"):
                raise KnowledgeError(
                    f"knowledge {key!r}: time {time!r} is not finite or older than the last "
                    f"sample at {last!r}"
                )
            self._known.setdefault(key, decl)
            # appended under the same lock as the check, so two threads cannot reorder a key
            if pending is None:
                pending = self._pending[key] = deque(maxlen=self.keep)
            pending.append(Sample(time, value))

    # -- writing --------------------------------------------------------------------------------

    def update_persistency(self) -> int:
        """Write every buffered sample and changed declaration in ONE transaction, prune each
        key that holds a sixteenth more than ``keep`` rows back to ``keep``, and return how
        many samples were written.

        Each key's buffered samples go in as one row (its times and its values each one JSON
        array), all rows in one ``executemany``. On a failure nothing is written, the samples
        go back to the buffer and :class:`KnowledgeError` says why.
        """
        with self._db_lock:
            db = self._open_db()
            with self._buf_lock:
                batch, self._pending = self._pending, {}
                for key, queue in batch.items():
                    # newest time of each key, kept for register_knowledge_update's check
                    self._last[key] = queue[-1].time
                known = dict(self._known)
            kb = self._kb
            if kb is not None:
                known.update(kb.declarations())
            for key, queue in batch.items():
                if key not in known:  # buffered without a declaration: its first value's type
                    known[key] = Declaration(key, infer_type(queue[0].value))
            changed = [d for key, d in known.items() if self._written.get(key) != d]
            if not batch and not changed:
                return 0
            rows: list[tuple[str, int, float, str, str, str]] = []
            counts: dict[str, int] = {}
            for key, queue in batch.items():
                times, values = zip(*queue, strict=True)
                rows.append(
                    (key, len(times), times[-1], known[key].type, _times_text(times),
                     encode(values))
                )
                counts[key] = self._counts.get(key, 0) + len(queue)
            # a key is pruned back to `keep` once it holds a sixteenth more: pruning every flush
            # rewrote the rows at each key's start in every transaction
            pruned = [key for key, count in counts.items() if count > self.keep + self.keep // 16]
            try:
                db.execute("BEGIN IMMEDIATE")
                db.executemany(
                    "INSERT OR REPLACE INTO declarations VALUES (?, ?, ?, ?, ?)",
                    [_declaration_row(d) for d in changed],
                )
                db.executemany(
                    'INSERT INTO batches (key, count, last, type, times, "values") '
                    "VALUES (?, ?, ?, ?, ?, ?)",
                    rows,
                )
                for key in pruned:
                    _prune(db, key, counts[key] - self.keep)
                db.execute("COMMIT")
            except sqlite3.Error as exc:
                if db.in_transaction:
                    db.execute("ROLLBACK")
                self._unbuffer(batch)
                raise KnowledgeError(f"cannot write knowledge to {self.path}: {exc}") from exc
            self._counts.update(counts)
            self._counts.update((key, self.keep) for key in pruned)
            for decl in changed:
                self._written[decl.key] = decl
            with self._buf_lock:
                for decl in changed:
                    self._known[decl.key] = decl
            return sum(len(queue) for queue in batch.values())

    def _unbuffer(self, batch: dict[str, deque[Sample]]) -> None:
        """Put a batch that could not be written back in front of what came since."""
        with self._buf_lock:
            for key, queue in batch.items():
                newer = self._pending.get(key)
                if newer:
                    queue.extend(newer)
                self._pending[key] = queue

    def _open_db(self) -> sqlite3.Connection:
        if self._db is None:
            raise KnowledgeError(f"knowledge file {self.path} is closed")
        return self._db

    # -- restoring ------------------------------------------------------------------------------

    def restore(self, kb: KnowledgeBase, *, strict: bool = False) -> int:
        """Load the stored declarations and the last ``history`` samples of every key into
        ``kb``; return how many samples.

        A key ``kb`` already declares keeps ``kb``'s declaration and stored samples are converted
        to it (ints to floats). Stored samples that do not fit it (the application changed the
        key's type or bounds) are skipped with a warning, or, if ``strict``, stop the restore.
        A key ``kb`` already holds samples of is refused. Errors come before anything is loaded.
        """
        with self._db_lock:
            db = self._open_db()
            stored = dict(self._written)
            keys = list(stored)
            on_disk = db.execute("SELECT DISTINCT key FROM batches")
            keys += [key for (key,) in on_disk if key not in stored]
            plan: list[tuple[str, Declaration | None, list[Sample]]] = []
            for key in keys:
                if kb.read_sample(key) is not None:
                    raise KnowledgeError(
                        f"cannot restore {key!r} from {self.path}: the knowledge base already "
                        "holds samples of it (restore into a fresh knowledge base)"
                    )
                current = kb.declaration(key)
                decl = current or stored.get(key)
                rows = self._newest(db, key, decl.history if decl else kb.default_history)
                if decl is None:  # samples without a stored declaration: infer, as on a write
                    decl = Declaration(key, infer_type(rows[0][1]), kb.default_history)
                samples = self._check_rows(decl, rows, strict)
                plan.append((key, None if current else decl, samples))
            total = 0
            for key, decl, samples in plan:
                if decl is not None:
                    kb.declare(
                        key,
                        decl.type,
                        history=decl.history,
                        minimum=decl.minimum,
                        maximum=decl.maximum,
                    )
                total += kb.load_samples(key, samples)
            return total

    def _newest(self, db: sqlite3.Connection, key: str, limit: int) -> list[tuple[float, Any]]:
        """The newest ``limit`` (time, value) pairs of ``key`` on disk, oldest first."""
        newest_first: list[list[tuple[float, Any]]] = []
        found = 0
        for times, values in db.execute(
            'SELECT times, "values" FROM batches WHERE key = ? ORDER BY seq DESC', (key,)
        ):
            try:
                times, values = decode(times), decode(values)
                if not isinstance(times, list) or not isinstance(values, list):
                    raise ValueError("a batch's times and values are not JSON arrays")
                if len(times) != len(values):
                    raise ValueError(f"{len(times)} times for {len(values)} values")
            except ValueError as exc:
                raise KnowledgeError(f"{self.path} is damaged: key {key!r}: {exc}") from exc
            newest_first.append(list(zip(times, values, strict=True)))
            found += len(times)
            if found >= limit:
                break
        return [pair for batch in reversed(newest_first) for pair in batch][-limit:]

    def _check_rows(
        self, decl: Declaration, rows: list[tuple[float, Any]], strict: bool
    ) -> list[Sample]:
        check = make_check(decl)
        samples: list[Sample] = []
        skipped: list[KnowledgeError] = []
        last = _BEFORE_ALL
        for time, value in rows:
            try:
                if isinstance(time, bool) or not isinstance(time, int | float):
                    raise ValueError(f"time {time!r} is not a number")
                if not last <= time:  # only a file edited by hand can get here
                    raise ValueError(f"time goes back to {time!r} after {last!r}")
                last = time
            except ValueError as exc:
                raise KnowledgeError(f"{self.path} is damaged: key {decl.key!r}: {exc}") from exc
            try:
                samples.append(Sample(float(time), check(value)))
            except KnowledgeError as exc:
                if strict:
                    raise KnowledgeError(
                        f"cannot restore {decl.key!r} from {self.path}: {exc}; declare the key "
                        "as it was stored, or delete the file to start afresh"
                    ) from exc
                skipped.append(exc)
        if skipped:
            _log.warning(
                "%s: skipped %d stored sample(s) of %r that do not fit its declaration, e.g. %s",
                self.path,
                len(skipped),
                decl.key,
                skipped[0],
            )
        return samples

    # -- closing --------------------------------------------------------------------------------

    @property
    def closed(self) -> bool:
        return self._db is None

    def _close(self) -> None:
        with self._db_lock:
            if self._db is not None:
                self._db.close()  # the last connection: SQLite checkpoints and removes the WAL
                self._db = None
                _release_lock(self._lock_fd)
                self._lock_fd = None


def _times_text(times: Sequence[float]) -> str:
    """The JSON array of finite floats (what a buffer's times are): their reprs, which are their
    JSON texts, joined; the JSON encoder's set-up cost more than this per flush and key."""
    return f"[{','.join(map(repr, times))}]"


def _prune(db: sqlite3.Connection, key: str, excess: int) -> None:
    """Delete the oldest ``excess`` samples of ``key``: whole batches, then the head of one."""
    doomed: list[int] = []
    cut: tuple[int, int, int] | None = None  # (seq, count, how many of its oldest go)
    oldest_first = db.execute("SELECT seq, count FROM batches WHERE key = ? ORDER BY seq", (key,))
    for seq, count in oldest_first:  # read only as far as the excess reaches
        if count > excess:
            cut = (seq, count, excess) if excess > 0 else None
            break
        doomed.append(seq)
        excess -= count
    oldest_first.close()
    db.executemany("DELETE FROM batches WHERE seq = ?", [(seq,) for seq in doomed])
    if cut is not None:
        seq, count, head = cut
        times, values = db.execute(
            'SELECT times, "values" FROM batches WHERE seq = ?', (seq,)
        ).fetchone()
        db.execute(
            'UPDATE batches SET count = ?, times = ?, "values" = ? WHERE seq = ?',
            (count - head, encode(decode(times)[head:]), encode(decode(values)[head:]), seq),
        )


def _convert_schema_1(db: sqlite3.Connection, path: Path) -> None:
    """Rewrite a schema-1 file's samples (one row per sample, written by an earlier rasm) as
    batches, inside the caller's transaction (a damaged value leaves the file as it was)."""
    runs: dict[str, tuple[str, list[float], list[object]]] = {}
    for key, time, type_, text in db.execute(
        "SELECT key, time, type, value FROM samples ORDER BY seq"
    ):
        try:
            value = decode(text)
        except ValueError as exc:
            raise KnowledgeError(f"{path} is damaged: key {key!r}: {exc}") from exc
        runs.setdefault(key, (type_, [], []))
        runs[key][1].append(time)
        runs[key][2].append(value)
    db.executemany(
        'INSERT INTO batches (key, count, last, type, times, "values") VALUES (?, ?, ?, ?, ?, ?)',
        [(key, len(times), times[-1], type_, encode(times), encode(values))
         for key, (type_, times, values) in runs.items()],
    )
    db.execute("DROP TABLE samples")


def _declaration(
    path: Path, key: str, type_: str, history: int, lo: str | None, hi: str | None
) -> Declaration:
    try:
        return Declaration(
            key,
            type_,
            history,
            None if lo is None else decode(lo),
            None if hi is None else decode(hi),
        )
    except (KnowledgeError, ValueError) as exc:
        raise KnowledgeError(f"{path}: bad stored declaration of {key!r}: {exc}") from exc


def _declaration_row(decl: Declaration) -> tuple[str, str, int, str | None, str | None]:
    return (
        decl.key,
        decl.type,
        decl.history,
        None if decl.minimum is None else encode(decl.minimum),
        None if decl.maximum is None else encode(decl.maximum),
    )


def _take_lock(path: Path) -> int | None:
    """Lock ``PATH.lock`` so that one storage at a time writes ``path`` (POSIX only)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows: documented as unguarded
        return None
    lock_path = path.with_name(path.name + ".lock")
    try:
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise KnowledgeError(
            f"opening the knowledge store {path} failed: creating its lock file {lock_path}: "
            f"{describe_error(exc)}"
        ) from exc
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        try:
            owner = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
        finally:
            os.close(fd)
        who = f"pid {owner}" if owner.isdigit() else "another process"
        raise KnowledgeError(
            f"knowledge file {path} is in use by {who} (another rasm run of this app): wait "
            "for it to end or stop it, or give this run another store (knowledge: sqlite:PATH)"
        ) from exc
    # the lock file names its holder, for the message a second run gets
    os.ftruncate(fd, 0)
    os.pwrite(fd, str(os.getpid()).encode("ascii"), 0)
    return fd


def _release_lock(fd: int | None) -> None:
    if fd is not None:
        os.close(fd)  # closing the descriptor releases the flock
