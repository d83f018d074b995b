"""Knowledge in Redis: the Knowledge Manager's API shared by every process of a distributed loop.

:class:`RedisKnowledgeBase` is a :class:`~rasm.knowledge.KnowledgeBase` whose samples live in a
Redis server instead of this process, so a value one process registers is read by all of them,
with the same bounded history, the same type checks and the same time rule (times never decrease
per key, now across processes). The runtime does not need to know which one it has.

Layout, under a namespace ``NS`` (default ``rasm``; the braces keep every key of a namespace in
one Redis Cluster slot):

- ``{NS}:decl`` — hash: key → its declaration as JSON ``[type, history, minimum, maximum]``;
- ``{NS}:keys`` — list: the keys in the order they became known;
- ``{NS}:k:KEY`` — sorted set: one member per sample, score = the sample's time, member =
  ``SEQ|JSON`` (a zero-padded global sequence number, so equal times keep their order, then the
  value's JSON); trimmed to the declaration's ``history`` on every write;
- ``{NS}:seq`` — the sequence counter; ``{NS}:events`` — the pub/sub channel of registrations.

Each registration is one Lua script (one round trip): it checks that the writer checked the value
against the declaration in force and that time does not go back, adds, trims and publishes, all
atomically. Durability is Redis's own (``appendonly yes`` for an append-only file).
"""

from __future__ import annotations

import json
import logging
import math
import secrets
import threading
from collections.abc import Iterable
from typing import Any
from urllib.parse import parse_qsl, urlencode, urlsplit, urlunsplit

import redis

from rasm.errors import KnowledgeError
from rasm.knowledge.base import KnowledgeBase, Sample, Subscription
from rasm.knowledge.storage import Storage
from rasm.knowledge.values import (
    DEFAULT_HISTORY,
    Check,
    Declaration,
    decode,
    encode,
    infer_type,
    make_check,
)

__all__ = ["DEFAULT_NAMESPACE", "RedisKnowledgeBase", "RedisStorage"]

_log = logging.getLogger("rasm.knowledge")

DEFAULT_NAMESPACE = "rasm"

# KEYS: decl hash, key list, series, seq counter, channel
# ARGV: key, declaration JSON, history, notify (0/1), writer id, then time, value pairs
_APPEND = """
local decl = redis.call('HGET', KEYS[1], ARGV[1])
if not decl then
  redis.call('HSET', KEYS[1], ARGV[1], ARGV[2])
  redis.call('RPUSH', KEYS[2], ARGV[1])
elseif decl ~= ARGV[2] then
  return {'decl', decl}
end
local last = redis.call('ZRANGE', KEYS[3], -1, -1, 'WITHSCORES')
local lastt = nil
if #last > 0 then lastt = tonumber(last[2]) end
local first = 6
local n = (#ARGV - first + 1) / 2
for i = 0, n - 1 do
  local t = tonumber(ARGV[first + 2 * i])
  if lastt ~= nil and t < lastt then
    return {'time', ARGV[first + 2 * i], last[2] or tostring(lastt)}
  end
  lastt = t
end
local seq = redis.call('INCRBY', KEYS[4], n) - n
for i = 0, n - 1 do
  seq = seq + 1
  local member = string.format('%020d', seq) .. '|' .. ARGV[first + 2 * i + 1]
  redis.call('ZADD', KEYS[3], ARGV[first + 2 * i], member)
  if ARGV[4] == '1' then
    redis.call('PUBLISH', KEYS[5], cjson.encode({w = ARGV[5], k = ARGV[1],
      t = ARGV[first + 2 * i], m = member}))
  end
end
redis.call('ZREMRANGEBYRANK', KEYS[3], 0, -(tonumber(ARGV[3]) + 1))
return {'ok', tostring(seq)}
"""


def _decl_json(decl: Declaration) -> str:
    return json.dumps([decl.type, decl.history, decl.minimum, decl.maximum])


def _decl_from(key: str, text: str | bytes) -> Declaration:
    try:
        type_, history, lo, hi = json.loads(text)
        return Declaration(key, type_, history, lo, hi)
    except (ValueError, TypeError, KnowledgeError) as exc:
        raise KnowledgeError(f"Redis holds a bad declaration of {key!r}: {text!r}") from exc


def _sample(member: str | bytes, score: float) -> Sample:
    text = member.decode() if isinstance(member, bytes) else member
    return Sample(float(score), decode(text.partition("|")[2]))


def parse_redis_url(url: str) -> tuple[str, str]:
    """``(url for redis-py, namespace)`` of ``redis://HOST:PORT/DB[?namespace=NS]``."""
    parts = urlsplit(url.strip())
    if parts.scheme not in ("redis", "rediss", "unix") or not (parts.hostname or parts.path):
        raise KnowledgeError(
            f"bad Redis knowledge store {url!r}: write redis://HOST:PORT/DB "
            "(optionally ?namespace=NAME)"
        )
    query = parse_qsl(parts.query)
    namespace = DEFAULT_NAMESPACE
    rest = []
    for name, value in query:
        if name == "namespace":
            namespace = value
        else:
            rest.append((name, value))
    if not namespace or any(c in namespace for c in "{}"):
        raise KnowledgeError(
            f"bad namespace {namespace!r} in {url!r}: give a non-empty name without braces"
        )
    plain = urlunsplit((parts.scheme, parts.netloc, parts.path, urlencode(rest), ""))
    return plain, namespace


class RedisKnowledgeBase(KnowledgeBase):
    """A :class:`KnowledgeBase` kept in Redis (see the module doc); same methods, same errors.

    ``url`` is ``redis://HOST:PORT/DB``; ``namespace`` separates applications sharing a server.
    ``client`` may be given instead (a ``redis.Redis``). Subscribers are called for this
    process's registrations on the writer's thread before ``register_knowledge`` returns (as in
    memory), and for other processes' registrations on a listener thread started by the first
    :meth:`subscribe`. Call :meth:`close` at the end.
    """

    def __init__(
        self,
        url: str | None = None,
        *,
        namespace: str | None = None,
        client: redis.Redis | None = None,
        default_history: int = DEFAULT_HISTORY,
        notify: bool = True,
    ) -> None:
        super().__init__(default_history=default_history)
        if client is None:
            if url is None:
                raise KnowledgeError("RedisKnowledgeBase needs a redis:// URL or a client")
            plain, from_url = parse_redis_url(url)
            namespace = namespace or from_url
            client = redis.Redis.from_url(plain)
        self.url = url
        self.namespace = namespace or DEFAULT_NAMESPACE
        self.notify = notify
        self.writer = secrets.token_hex(8)  # tells our own notifications from others'
        self._redis = client
        ns = "{" + self.namespace + "}"
        self._decl_key = f"{ns}:decl"
        self._keys_key = f"{ns}:keys"
        self._seq_key = f"{ns}:seq"
        self.channel = f"{ns}:events"
        self._prefix = f"{ns}:k:"
        self._append = client.register_script(_APPEND)
        self._checks: dict[str, tuple[Declaration, str, Check]] = {}
        self._listener: threading.Thread | None = None
        self._pubsub: Any = None
        self._closing = threading.Event()
        try:
            client.ping()
        except redis.RedisError as exc:
            raise KnowledgeError(
                f"cannot reach the Redis knowledge store {url or client!r}: {exc} "
                "(is redis-server running there?)"
            ) from exc

    def __repr__(self) -> str:
        return f"RedisKnowledgeBase({self.url!r}, namespace={self.namespace!r})"

    def _series_key(self, key: str) -> str:
        return self._prefix + key

    def _call(self, what: str, fn: Any, *args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except redis.RedisError as exc:
            raise KnowledgeError(f"Redis knowledge store: cannot {what}: {exc}") from exc

    # -- declarations ---------------------------------------------------------------------------

    def _cached(self, decl: Declaration) -> tuple[Declaration, str, Check]:
        entry = (decl, _decl_json(decl), make_check(decl))
        self._checks[decl.key] = entry
        return entry

    def _current(self, key: str) -> tuple[Declaration, str, Check] | None:
        entry = self._checks.get(key)
        if entry is not None:
            return entry
        text = self._call("read a declaration", self._redis.hget, self._decl_key, key)
        return None if text is None else self._cached(_decl_from(key, text))

    def declare(
        self,
        key: str,
        type: str,
        *,
        history: int | None = None,
        minimum: float | None = None,
        maximum: float | None = None,
    ) -> Declaration:
        """As :meth:`KnowledgeBase.declare`, for every process at once (atomic in Redis)."""
        decl = Declaration(
            key, type, self.default_history if history is None else history, minimum, maximum
        )
        text = _decl_json(decl)
        series = self._series_key(key)
        with self._lock:
            try:
                with self._redis.pipeline() as pipe:
                    while True:
                        try:
                            pipe.watch(self._decl_key, series)
                            old = pipe.hget(self._decl_key, key)
                            if old is not None and (old.decode() if isinstance(old, bytes)
                                                    else old) == text:
                                pipe.unwatch()
                                break
                            members = pipe.zrange(series, 0, -1, withscores=True)
                            rows = self._convert(key, decl, members, type)
                            pipe.multi()
                            if old is None:
                                pipe.rpush(self._keys_key, key)
                            pipe.hset(self._decl_key, key, text)
                            if members:
                                pipe.delete(series)
                                if rows:
                                    pipe.zadd(series, rows)
                            pipe.execute()
                            break
                        except redis.WatchError:
                            continue  # another process changed the key meanwhile: again
            except redis.RedisError as exc:
                raise KnowledgeError(
                    f"Redis knowledge store: cannot declare {key!r}: {exc}"
                ) from exc
            self._cached(decl)
        return decl

    @staticmethod
    def _convert(
        key: str, decl: Declaration, members: list[tuple[Any, float]], type_: str
    ) -> dict[str, float]:
        check = make_check(decl)
        rows: dict[str, float] = {}
        for member, score in members[-decl.history :]:
            text = member.decode() if isinstance(member, bytes) else member
            seq, _, value = text.partition("|")
            try:
                converted = check(decode(value))
            except KnowledgeError as exc:
                raise KnowledgeError(
                    f"cannot declare {key!r} as {type_}: a sample it already holds does not fit "
                    f"({exc})"
                ) from exc
            rows[f"{seq}|{encode(converted)}"] = score
        return rows

    def declaration(self, key: str) -> Declaration | None:
        """The declaration of ``key`` in force in Redis (inferred at its first write if never
        declared)."""
        text = self._call("read a declaration", self._redis.hget, self._decl_key, key)
        return None if text is None else _decl_from(key, text)

    def declarations(self) -> dict[str, Declaration]:
        """All declarations, by key, in the order the keys became known."""
        texts = self._call("read declarations", self._redis.hgetall, self._decl_key)
        decls = {
            (k.decode() if isinstance(k, bytes) else k): v for k, v in texts.items()
        }
        return {key: _decl_from(key, decls[key]) for key in self.keys() if key in decls}

    # -- writing --------------------------------------------------------------------------------

    def _store(self, key: str, value: Any, time: float) -> Sample:
        # what register_knowledge and register_values store; the time rule holds across processes
        time = self._time(key, time)
        if not -math.inf < time < math.inf:
            raise self._bad_time(key, time, -math.inf)
        with self._lock:
            value = self._append_samples(key, [(time, value)], notify=self.notify, first=value)[0]
            return Sample(time, value)

    def load_samples(self, key: str, samples: Iterable[Sample]) -> int:
        """Append samples in bulk without notifying subscribers (nor other processes)."""
        samples = [(self._time(key, t), v) for t, v in samples]
        if not samples:
            return 0
        with self._lock:
            self._append_samples(key, samples, notify=False, first=samples[0][1])
        return len(samples)

    def _append_samples(
        self, key: str, samples: list[tuple[float, Any]], *, notify: bool, first: Any
    ) -> list[Any]:
        """Check and append; returns the canonical values. Retries when another process
        re-declared the key between our read of its declaration and the write."""
        for _attempt in range(5):
            entry = self._current(key) or self._cached(
                Declaration(key, infer_type(first), self.default_history)
            )
            decl, text, check = entry
            values = [check(v) for _, v in samples]
            for t, _ in samples:
                if math.isnan(t) or math.isinf(t):
                    raise self._bad_time(key, t, -math.inf)
            args: list[Any] = [key, text, decl.history, "1" if notify else "0", self.writer]
            for (t, _), v in zip(samples, values, strict=True):
                args += [repr(t), encode(v)]
            keys = [self._decl_key, self._keys_key, self._series_key(key), self._seq_key,
                    self.channel]
            answer = self._call(f"register {key!r}", self._append, keys=keys, args=args)
            status = answer[0].decode() if isinstance(answer[0], bytes) else answer[0]
            if status == "ok":
                return values
            if status == "decl":
                self._cached(_decl_from(key, answer[1]))
                continue
            time_text, last_text = (
                a.decode() if isinstance(a, bytes) else a for a in answer[1:3]
            )
            raise self._bad_time(key, float(time_text), float(last_text))
        raise KnowledgeError(f"knowledge {key!r}: its declaration keeps changing; try again")

    # -- reading --------------------------------------------------------------------------------

    def read_knowledge(self, key: str, default: Any = None) -> Any:
        """The latest value of ``key``, or ``default`` if it has none."""
        sample = self.read_sample(key)
        return default if sample is None else sample.value

    def read_sample(self, key: str) -> Sample | None:
        """The latest sample of ``key`` (from any process), or None."""
        found = self._call(
            f"read {key!r}", self._redis.zrange, self._series_key(key), -1, -1, withscores=True
        )
        return _sample(*found[0]) if found else None

    def history(
        self,
        key: str,
        *,
        last: int | None = None,
        since: float | None = None,
        until: float | None = None,
    ) -> list[Sample]:
        """As :meth:`KnowledgeBase.history`: one Redis range query (O(log n) plus the answer)."""
        if last is not None and (isinstance(last, bool) or not isinstance(last, int) or last < 0):
            raise KnowledgeError(
                f"history of {key!r}: last must be a whole number >= 0, got {last!r}"
            )
        if last == 0:
            return []
        series = self._series_key(key)
        r = self._redis
        if since is None and until is None:
            start = 0 if last is None else -last
            found = self._call(f"read {key!r}", r.zrange, series, start, -1, withscores=True)
        else:
            lo = "-inf" if since is None else repr(float(since))
            hi = "+inf" if until is None else repr(float(until))
            if last is None:
                found = self._call(
                    f"read {key!r}", r.zrangebyscore, series, lo, hi, withscores=True
                )
            else:
                found = self._call(
                    f"read {key!r}", r.zrevrangebyscore, series, hi, lo, start=0, num=last,
                    withscores=True,
                )
                found.reverse()
        return [_sample(member, score) for member, score in found]

    def keys(self) -> list[str]:
        """Every key declared or registered (by any process), in the order they became known."""
        found = self._call("list keys", self._redis.lrange, self._keys_key, 0, -1)
        return [k.decode() if isinstance(k, bytes) else k for k in found]

    def snapshot(self) -> dict[str, Any]:
        """The latest value of every key that has one (one pipelined round trip)."""
        keys = self.keys()
        pipe = self._redis.pipeline(transaction=False)
        for key in keys:
            pipe.zrange(self._series_key(key), -1, -1, withscores=True)
        found = self._call("read a snapshot", pipe.execute)
        return {key: _sample(*rows[0]).value for key, rows in zip(keys, found, strict=True) if rows}

    def __contains__(self, key: object) -> bool:
        return isinstance(key, str) and bool(
            self._call("read a declaration", self._redis.hexists, self._decl_key, key)
        )

    def clear(self) -> int:
        """Delete every key of this namespace (e.g. before a fresh simulated run); returns how
        many knowledge keys there were."""
        keys = self.keys()
        with self._lock:
            self._call(
                "clear the namespace",
                self._redis.delete,
                self._decl_key, self._keys_key, self._seq_key,
                *(self._series_key(k) for k in keys),
            )
            self._checks.clear()
        return len(keys)

    # -- subscribers ----------------------------------------------------------------------------

    def _subscribe(self, subscription: Subscription) -> Subscription:
        # subscribers are also called for other processes' registrations, on this knowledge
        # base's listener thread
        super()._subscribe(subscription)
        with self._lock:
            if self._listener is None and self.notify:
                self._start_listener()
        return subscription

    def _start_listener(self) -> None:
        pubsub = self._redis.pubsub(ignore_subscribe_messages=True)
        self._call("subscribe to registrations", pubsub.subscribe, self.channel)
        # the SUBSCRIBE is confirmed before subscribe() returns, so no later write is missed
        self._call("subscribe to registrations", pubsub.get_message, timeout=5.0)
        self._pubsub = pubsub
        self._listener = threading.Thread(
            target=self._listen, args=(pubsub,), name=f"rasm-knowledge-{self.namespace}",
            daemon=True,
        )
        self._listener.start()

    def _listen(self, pubsub: Any) -> None:
        lost = False
        while True:
            try:
                message = pubsub.get_message(timeout=1.0)
            except (redis.RedisError, OSError, ValueError, AttributeError) as exc:
                if self._pubsub is None:
                    return  # closed
                if not lost:
                    # redis-py reconnects and subscribes again on the next read; notices
                    # published meanwhile are lost (pub/sub keeps nothing), samples are not
                    _log.warning("lost the Redis registration feed (%s); reconnecting", exc)
                    lost = True
                self._closing.wait(0.2)  # a pause between attempts; close() ends it at once
                continue
            if self._pubsub is None:
                return
            if lost:
                _log.info("the Redis registration feed is back")
                lost = False
            if message is None or message.get("type") != "message":
                continue
            try:
                event = json.loads(message["data"])
                if event["w"] == self.writer:
                    continue
                sample = _sample(event["m"], float(event["t"]))
                key = event["k"]
            except (ValueError, KeyError, TypeError):
                _log.warning("malformed registration notice ignored: %r", message.get("data"))
                continue
            self._notify([(key, sample)])

    def close(self) -> None:
        """Stop the listener and release the connections (idempotent)."""
        pubsub, self._pubsub = self._pubsub, None
        self._closing.set()
        if pubsub is not None:
            try:
                pubsub.close()
            except redis.RedisError:
                pass
        if self._listener is not None and self._listener is not threading.current_thread():
            self._listener.join(timeout=5.0)
        self._listener = None
        self._redis.close()

    def __enter__(self) -> RedisKnowledgeBase:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class RedisStorage(Storage):
    """The Storage Manager's face of a :class:`RedisKnowledgeBase`.

    Redis is itself the store, so there is nothing to buffer or to restore: a registration is in
    Redis when ``register_knowledge`` returns. This class lets the runtime treat every store
    alike: ``register_knowledge_update`` counts, ``update_persistency`` returns how many samples
    were counted since its last call, ``restore`` loads nothing, and ``close`` closes the
    knowledge base's connections.
    """

    def __init__(self, kb: RedisKnowledgeBase) -> None:
        super().__init__()
        self.redis_knowledge = kb
        self._count = 0
        self._count_lock = threading.Lock()
        self._closed = False

    def register_knowledge_update(self, key: str, sample: Sample) -> None:
        """Count one sample as persisted (its knowledge base already wrote it to Redis)."""
        self.buffer(key, sample)

    def buffer(self, key: str, sample: Sample) -> None:
        self.buffer_all([(key, sample)])

    def buffer_all(self, samples: list[tuple[str, Sample]]) -> None:
        with self._count_lock:
            self._count += len(samples)

    def update_persistency(self) -> int:
        """How many samples were registered since the last call (all already in Redis)."""
        with self._count_lock:
            count, self._count = self._count, 0
        return count

    def restore(self, kb: KnowledgeBase, *, strict: bool = False) -> int:
        """Nothing to load: the Redis knowledge base reads Redis directly."""
        return 0

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def location(self) -> str:
        return self.redis_knowledge.url

    def _close(self) -> None:
        if not self._closed:
            self._closed = True
            self.redis_knowledge.close()
