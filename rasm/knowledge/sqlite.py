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
from itertools import repeat
from pathlib import Path

from rasm.errors import KnowledgeError
from rasm.knowledge.base import KnowledgeBase, Sample
from rasm.knowledge.storage import Storage
from rasm.knowledge.values import (
    Declaration,
    decode,
    encode,
    encode_all,
    infer_type,
    make_check,
)

_log = logging.getLogger("rasm.knowledge")

SCHEMA_VERSION = 1
DEFAULT_KEEP = 10_000
"""Samples kept on disk per key unless ``keep`` says otherwise."""

_SCHEMA = """
CREATE TABLE IF NOT EXISTS declarations (
    key TEXT PRIMARY KEY,
    type TEXT NOT NULL,
    history INTEGER NOT NULL,
    minimum TEXT,            -- JSON number or NULL (TEXT: an int bound keeps every digit)
    maximum TEXT
);
CREATE TABLE IF NOT EXISTS samples (
    seq INTEGER PRIMARY KEY, -- insertion order: orders samples of a key even at equal times
    key TEXT NOT NULL,
    time REAL NOT NULL,
    type TEXT NOT NULL,
    value TEXT NOT NULL      -- JSON text (Python's dialect: NaN and Infinity allowed)
);
CREATE INDEX IF NOT EXISTS samples_by_key ON samples (key, seq);
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
        self._counts: dict[str, int] = {}  # rows on disk per key (we are the only writer)
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

    # -- opening --------------------------------------------------------------------------------

    def _connect(self) -> sqlite3.Connection:
        try:
            # isolation_level=None: we issue BEGIN/COMMIT ourselves, one transaction per flush
            db = sqlite3.connect(str(self.path), check_same_thread=False, isolation_level=None)
        except sqlite3.Error as exc:
            raise KnowledgeError(f"cannot open knowledge file {self.path}: {exc}") from exc
        try:
            version = db.execute("PRAGMA user_version").fetchone()[0]
            tables = {row[0] for row in db.execute("SELECT name FROM sqlite_master")}
            if version != SCHEMA_VERSION and (version != 0 or tables):
                raise KnowledgeError(
                    f"{self.path} is not a rasm knowledge file of schema {SCHEMA_VERSION} "
                    f"(user_version {version}): point sqlite: at another file"
                )
            mode = db.execute("PRAGMA journal_mode=WAL").fetchone()[0]
            if str(mode).lower() != "wal":
                _log.warning("%s: journal mode is %s, not WAL (file system?)", self.path, mode)
            db.execute(f"PRAGMA synchronous={'FULL' if self.durable else 'NORMAL'}")
            # one transaction: a kill half-way never leaves tables without the version mark
            db.executescript(f"BEGIN; {_SCHEMA} PRAGMA user_version={SCHEMA_VERSION}; COMMIT;")
            for key, type_, history, lo, hi in db.execute(
                "SELECT key, type, history, minimum, maximum FROM declarations"
            ):
                decl = _declaration(self.path, key, type_, history, lo, hi)
                self._written[key] = self._known[key] = decl
            for key, count, last in db.execute(
                "SELECT key, COUNT(*), MAX(time) FROM samples GROUP BY key"
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
        with self._buf_lock:
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

        The batch goes to SQLite as one ``executemany`` per table, its values encoded key by
        key in one call of the JSON encoder each. On a failure nothing is written, the samples
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
            rows: list[tuple[str, float, str, str]] = []
            counts: dict[str, int] = {}
            for key, queue in batch.items():
                times, values = zip(*queue, strict=True)
                kind = known[key].type
                rows.extend(zip(repeat(key), times, repeat(kind), encode_all(values)))
                counts[key] = self._counts.get(key, 0) + len(queue)
            # the oldest rows of each key beyond `keep` (the index on (key, seq) finds them),
            # once there are a sixteenth more: deleting them every flush dirtied the pages at
            # each key's start in every transaction
            pruned = [(key, count - self.keep) for key, count in counts.items()
                      if count > self.keep + self.keep // 16]
            try:
                db.execute("BEGIN IMMEDIATE")
                db.executemany(
                    "INSERT OR REPLACE INTO declarations VALUES (?, ?, ?, ?, ?)",
                    [_declaration_row(d) for d in changed],
                )
                db.executemany(
                    "INSERT INTO samples (key, time, type, value) VALUES (?, ?, ?, ?)", rows
                )
                db.executemany(
                    "DELETE FROM samples WHERE seq IN (SELECT seq FROM samples "
                    "WHERE key = ? ORDER BY seq LIMIT ?)",
                    pruned,
                )
                db.execute("COMMIT")
            except sqlite3.Error as exc:
                if db.in_transaction:
                    db.execute("ROLLBACK")
                self._unbuffer(batch)
                raise KnowledgeError(f"cannot write knowledge to {self.path}: {exc}") from exc
            self._counts.update(counts)
            self._counts.update((key, self.keep) for key, _ in pruned)
            for decl in changed:
                self._written[decl.key] = decl
            with self._buf_lock:
                for decl in changed:
                    self._known[decl.key] = decl
            return len(rows)

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
            on_disk = db.execute("SELECT DISTINCT key FROM samples")
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
                rows = db.execute(
                    "SELECT time, value FROM samples WHERE key = ? ORDER BY seq DESC LIMIT ?",
                    (key, decl.history if decl else kb.default_history),
                ).fetchall()
                rows.reverse()
                if decl is None:  # samples without a stored declaration: infer, as on a write
                    decl = Declaration(key, infer_type(decode(rows[0][1])), kb.default_history)
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

    def _check_rows(
        self, decl: Declaration, rows: list[tuple[float, str]], strict: bool
    ) -> list[Sample]:
        check = make_check(decl)
        samples: list[Sample] = []
        skipped: list[KnowledgeError] = []
        last = _BEFORE_ALL
        for time, text in rows:
            try:
                if not last <= time:  # only a file edited by hand can get here
                    raise ValueError(f"time goes back to {time!r} after {last!r}")
                last = time
                value = decode(text)
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
        raise KnowledgeError(f"cannot open knowledge file {path}: {exc}") from exc
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
