"""The manifest's ``knowledge:`` field: which store an application's knowledge lives in.

``memory`` keeps knowledge in memory only; ``sqlite:PATH`` also persists it to a SQLite file
(restored on start, so a restarted application continues from its last persisted state);
``redis://HOST:PORT/DB`` keeps it in a Redis server shared by every process of the application
(``?namespace=NAME`` separates applications on one server; see :mod:`rasm.knowledge.redis`).
"""

from __future__ import annotations

import os
from pathlib import Path

from rasm.errors import KnowledgeError
from rasm.knowledge.base import KnowledgeBase
from rasm.knowledge.sqlite import SqliteStorage
from rasm.knowledge.storage import Storage

_FORMS = "memory, sqlite:PATH or redis://HOST:PORT"


def open_knowledge(
    url: str, *, base_dir: str | os.PathLike[str] | None = None, fresh: bool = False
) -> tuple[KnowledgeBase, Storage | None]:
    """Open the knowledge store ``url`` names: a knowledge base and its storage (or None).

    A ``sqlite:PATH`` that is relative is taken from ``base_dir`` (the application folder;
    default the current directory); missing folders are created. Stored knowledge is restored
    and the storage attached, so every registration is buffered for ``update_persistency``.
    ``redis://`` gives a :class:`~rasm.knowledge.redis.RedisKnowledgeBase` and its
    :class:`~rasm.knowledge.redis.RedisStorage` (nothing to restore: the knowledge is read from
    Redis directly). ``fresh=True`` starts a SQLite file empty (what it held is deleted once
    its lock is taken).
    """
    if not isinstance(url, str):
        raise KnowledgeError(f"knowledge store must be text ({_FORMS}), got {url!r}")
    text = url.strip()
    scheme, colon, rest = text.partition(":")
    scheme = scheme.lower()
    if text.lower() == "memory":
        return KnowledgeBase(), None
    if colon and scheme == "sqlite":
        return _open_sqlite(rest, base_dir, url, fresh)
    if colon and scheme in ("redis", "rediss"):
        return _open_redis(text)
    raise KnowledgeError(f"unknown knowledge store {url!r}: expected {_FORMS}")


def _open_sqlite(
    rest: str, base_dir: str | os.PathLike[str] | None, url: str, fresh: bool
) -> tuple[KnowledgeBase, Storage]:
    if not rest.strip():
        raise KnowledgeError(f"knowledge store {url!r} names no file: write sqlite:PATH")
    if rest.startswith("//"):
        raise KnowledgeError(
            f"knowledge store {url!r}: write sqlite:PATH (e.g. sqlite:state/knowledge.db or "
            "sqlite:/var/lib/app/knowledge.db), without //"
        )
    path = Path(rest).expanduser()
    if not path.is_absolute():
        path = Path(base_dir if base_dir is not None else os.getcwd()) / path
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise KnowledgeError(
            f"knowledge store {url!r}: cannot create {path.parent}: {exc}"
        ) from exc
    kb = KnowledgeBase()
    storage = SqliteStorage(path, fresh=fresh)
    try:
        storage.restore(kb)
        storage.attach(kb)
    except BaseException:
        storage.close()
        raise
    return kb, storage


def _open_redis(url: str) -> tuple[KnowledgeBase, Storage]:
    try:
        from rasm.knowledge.redis import RedisKnowledgeBase, RedisStorage
    except ImportError as exc:  # pragma: no cover - redis is a dependency
        raise KnowledgeError(
            f"knowledge store {url!r} needs the redis package: pip install 'redis>=5'"
        ) from exc
    kb = RedisKnowledgeBase(url)
    return kb, RedisStorage(kb)
