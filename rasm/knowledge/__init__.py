"""rasm.knowledge: the Knowledge Manager's store and the Storage Manager's persistence.

``KnowledgeBase`` keeps typed values with a bounded history per key (``register_knowledge``,
``read_knowledge``, ``history``, ``subscribe``); ``SqliteStorage`` buffers registrations
(``register_knowledge_update``) and writes them in one transaction (``update_persistency``);
``open_knowledge`` opens what an application manifest's ``knowledge:`` field names;
``RedisKnowledgeBase`` is the same API kept in a Redis server that several processes share.
"""

from rasm.errors import KnowledgeError
from rasm.knowledge.base import KnowledgeBase, Sample, Subscription
from rasm.knowledge.sqlite import DEFAULT_KEEP, SqliteStorage
from rasm.knowledge.storage import Storage
from rasm.knowledge.url import open_knowledge
from rasm.knowledge.values import DEFAULT_HISTORY, TYPES, Declaration

__all__ = [
    "DEFAULT_HISTORY",
    "DEFAULT_KEEP",
    "TYPES",
    "Declaration",
    "KnowledgeBase",
    "KnowledgeError",
    "RedisKnowledgeBase",
    "RedisStorage",
    "Sample",
    "SqliteStorage",
    "Storage",
    "Subscription",
    "open_knowledge",
]


def __getattr__(name: str) -> object:
    # the Redis store loads redis-py only when asked for
    if name in ("RedisKnowledgeBase", "RedisStorage"):
        from rasm.knowledge import redis as _redis

        return getattr(_redis, name)
    raise AttributeError(f"module 'rasm.knowledge' has no attribute {name!r}")
