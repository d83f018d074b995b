"""Incremental temporal operators: O(1) amortised work per record, whatever the bounds.

Past sub-formulas over signals are written into the generated step function
(:mod:`rasm.properties.formula_code`); the classes here evaluate temporal operators whose
operands' values come late — a sub-formula above a future operator — and aggregates.

Values are three-valued: True, False, and None (inconclusive: it depends on records after the
end of the trace, which only the end of an offline trace says). An operand's values come **in
any order**, each as soon as it is decided (``put``): ``p and eventually[0, 5] q`` is false at a
record where p is false at once, while the records before it still wait for q. Each operator
decides its own values as soon as the operand values it has make them certain, and appends them
to ``out`` as ``(index, time, ns, value)``, in the order it decides them:

* :class:`WindowOr` — ``once[a,b]`` and ``eventually[a,b]`` (``historically``/``always`` are
  their negations): true as soon as a value in the window is true, false as soon as the window
  is complete (for the future: a record beyond it has come) and every value in it is false;
* :class:`SinceWindow`, :class:`UntilWindow` — ``since``/``until``, through an identity that
  holds in three-valued logic (:class:`UntilWindow`);
* :class:`WindowCore` — ``count/sum/avg/min/max``.

Times are compared as exact integer nanoseconds (``ns``; see :mod:`rasm.properties.times`), and
so are the bounds ``a`` and ``b`` (``b`` may be ``math.inf`` for the past). Every record enters
and leaves each structure once; finding the undecided records of a window and the first value
in a window not known to be false are union–find look-ups with path compression (amortised
near-constant), and records waiting for the same value wait in one group that moves as a whole.
Memory holds the records some undecided value may still need.
"""

from __future__ import annotations

import math
from collections import deque

__all__ = ["UNKNOWN", "FutureOr", "SinceWindow", "UntilWindow", "WindowCore", "WindowOr"]

NAN = math.nan
INF = math.inf
_SCALE_BITS = 1074  # every finite float is an integer multiple of 2**-1074
_SCALE = 1 << _SCALE_BITS

UNKNOWN = type("Unknown", (), {"__repr__": lambda self: "<unknown>"})()
BATCH = 64  # since/until forget records in batches of more than this many


def k_not(v):
    """Kleene's ``not`` (UNKNOWN stays unknown)."""
    return v if v is None or v is UNKNOWN else not v


def k_and(values):
    """Kleene's ``and`` of decided values (None: inconclusive)."""
    if False in values:
        return False
    return None if None in values else True


def k_or(a, b):
    """Kleene's ``or`` of two decided values (None: inconclusive)."""
    if a is True or b is True:
        return True
    return None if a is None or b is None else False


# --------------------------------------------------------------------------- aggregates


class WindowCore:
    """``count/sum/avg/min/max[a,b](v)`` over the records j with a <= t_i - t_j <= b.

    Records wait in ``pending`` until they are ``a`` old, then sit in ``window`` until they are
    more than ``b`` old. Undefined values (nan) make the aggregate undefined while in the
    window; inconclusive ones (None) make it inconclusive.

    Sums follow IEEE-754 binary64 and never raise: the finite values are summed exactly (as
    integers, in units of 2**-1074: every float and every int is a whole number of them) and
    the exact sum or average is rounded once, to ±inf beyond the largest float; an infinite
    value makes the result infinite, and +inf with -inf makes it undefined.
    """

    def __init__(self, op: str, a: int, b: int | float) -> None:
        self.op, self.a, self.b = op, a, b
        self.pending: deque = deque()
        self.window: deque = deque()
        self.total = 0  # exact: integer multiples of 2**-1074 (or a plain count)
        self.n = 0
        self.nan = 0
        self.none = 0
        self.up = self.down = 0  # +inf and -inf values in the window (sum and avg)
        self.mono: deque = deque()  # min/max candidates, monotonic

    def enter(self, item) -> None:
        """Record ``item`` ``(ns, value)`` joins the window (records join in time order)."""
        self.window.append(item)
        v = item[1]
        self.n += 1
        if v is None:
            self.none += 1
        elif v != v:
            self.nan += 1
        elif self.op == "count":
            self.total += 1 if v else 0
        elif self.op in ("sum", "avg"):
            try:
                num, den = v.as_integer_ratio()
            except OverflowError:  # ±inf
                if v > 0:
                    self.up += 1
                else:
                    self.down += 1
            else:
                self.total += num * (_SCALE // den)
        else:
            mono = self.mono
            if self.op == "min":
                while mono and mono[-1][1] >= v:
                    mono.pop()
            else:
                while mono and mono[-1][1] <= v:
                    mono.pop()
            mono.append(item)

    def _leave(self) -> None:
        item = self.window.popleft()
        v = item[1]
        self.n -= 1
        if v is None:
            self.none -= 1
        elif v != v:
            self.nan -= 1
        elif self.op == "count":
            self.total -= 1 if v else 0
        elif self.op in ("sum", "avg"):
            try:
                num, den = v.as_integer_ratio()
            except OverflowError:
                if v > 0:
                    self.up -= 1
                else:
                    self.down -= 1
            else:
                self.total -= num * (_SCALE // den)
        elif self.mono and self.mono[0] is item:
            self.mono.popleft()

    def push(self, ns: int, v):
        """The record at ``ns`` with value ``v``; returns the aggregate there."""
        item = (ns, v)
        if self.a == 0:
            self.enter(item)
        else:
            pending = self.pending
            pending.append(item)
            while pending and ns - pending[0][0] >= self.a:
                self.enter(pending.popleft())
        return self.at(ns)

    def at(self, ns: int):
        """The aggregate at a record at ``ns``, once every record at least ``a`` older has
        entered: the records more than ``b`` older leave first."""
        window = self.window
        while window and ns - window[0][0] > self.b:
            self._leave()
        return self.value()

    def value(self):
        if self.none:
            return None
        op = self.op
        if op == "count":
            return self.total
        if self.nan:
            return NAN
        if op in ("sum", "avg"):
            if self.up or self.down:
                return NAN if self.up and self.down else (INF if self.up else -INF)
            if op == "sum":
                return _rounded(self.total, _SCALE) if self.total else 0
            return _rounded(self.total, _SCALE * self.n) if self.n else NAN
        return self.mono[0][1] if self.mono else NAN


def _rounded(numerator: int, denominator: int) -> float:
    """The float nearest numerator / denominator; ±inf beyond the largest float."""
    try:
        return numerator / denominator
    except OverflowError:
        return INF if numerator > 0 else -INF


# --------------------------------------------------------------------------- windows

# the slots of a record in WindowOr.recs
_T, _NS, _VAL, _LO, _HI, _FIRST, _LAST, _DONE = range(8)


def _wait_on(groups: dict[int, list[int]], blocker: int, first: int, last: int) -> None:
    """Outputs ``first`` to ``last`` wait on record ``blocker``'s value, joining the group
    already waiting there (whose outputs all come after ours)."""
    later = groups.get(blocker)
    if later is None:
        groups[blocker] = [first, last]
    else:
        later[0] = first


class WindowOr:
    """``once[a,b] v`` (``past``) or ``eventually[a,b] v`` of a value decided in any order.

    :meth:`record` each record, in order; :meth:`put` the operand's value at a record when it
    is decided; :meth:`finish` at the end of the trace. Record i's window is the records
    j <= i with ``a <= t_i - t_j <= b`` (past) or j >= i with ``a <= t_j - t_i <= b`` (future).

    An output is true as soon as a value in its window is true: a true value at record u
    decides at once every output whose window holds u — a range of outputs, known when u
    arrived (future) or when it entered the windows (past). An output is false once its window
    is complete and every value in it is false: a complete window waits on its first value not
    known to be false (its *blocker*); the outputs waiting on one blocker form a range that
    moves on as a whole when the blocker turns out false, shedding the outputs whose windows end
    before the next blocker.
    """

    TIDY = 256  # records held before the first look for ones to forget

    def __init__(self, past: bool, a: int, b: int | float) -> None:
        self.past, self.a, self.b = past, a, b
        self.recs: list[list] = []  # recs[k] is record base + k
        self.base = 0
        self.newest = -1
        self.oldest = 0  # every output before it is decided
        self.out: deque = deque()
        self._done: dict[int, int] = {}  # decided output -> a later candidate (union-find)
        self._false: dict[int, int] = {}  # record whose value is false -> a later candidate
        self._groups: dict[int, list[int]] = {}  # blocker -> [first, last] waiting output
        # future: outputs before `closing` have a complete window, those before `opening`
        # know where their window starts; past: the windows of the newest record are
        # [low, high] (records up to `high` are at least a old, from `low` at most b old)
        self.closing = self.opening = self.low = 0
        self.high = -1
        self.last_true = -1  # past: the latest record at most `high` whose value is true
        self._tidy_at = self.TIDY  # records held when _tidy looks for ones to forget next

    # ------------------------------------------------------------------ input
    def record(self, i: int, t, ns: int) -> None:
        """Record ``i`` at ``ns`` (its time ``t`` as given) arrives.

        (The first record sets the window up; the next ones go straight to the past's or the
        future's method, which replaces this one.)"""
        self.base = self.oldest = self.closing = self.opening = self.low = i
        self.high = i - 1
        self.record = self._record_past if self.past else self._record_future
        self.record(i, t, ns)

    def _record_future(self, i: int, t, ns: int) -> None:
        rec = [t, ns, UNKNOWN, None, None, None, None, False]
        recs, base, a, b = self.recs, self.base, self.a, self.b
        recs.append(rec)
        self.newest = i
        j = self.opening
        while j <= i and ns - recs[j - base][_NS] >= a:
            recs[j - base][_LO] = i  # output j's window starts here
            j += 1
        self.opening = j
        j = self.closing
        while ns - recs[j - base][_NS] > b:  # stops at i at the latest
            self._close(j, i - 1)
            j += 1
        self.closing = j
        # this record lies in the windows of outputs closing .. opening - 1
        rec[_FIRST], rec[_LAST] = j, self.opening - 1
        if len(recs) > self._tidy_at:
            self._tidy()

    def _record_past(self, i: int, t, ns: int) -> None:
        rec = [t, ns, UNKNOWN, None, None, None, None, False]
        recs, base, a, b = self.recs, self.base, self.a, self.b
        recs.append(rec)
        self.newest = i
        p = self.high + 1
        while p <= i and ns - recs[p - base][_NS] >= a:  # old enough: enters the windows
            entering = recs[p - base]
            entering[_FIRST] = i
            if entering[_VAL] is True:
                self.last_true = p
            p += 1
        self.high = high = p - 1
        if b != INF:
            p = self.low
            while ns - recs[p - base][_NS] > b:  # too old: leaves the windows
                recs[p - base][_LAST] = i - 1
                p += 1
            self.low = p
        low = self.low
        rec[_LO], rec[_HI] = low, high
        if self.last_true >= low:
            self._decide(i, rec, True)
        elif low > high:
            self._decide(i, rec, False)
        else:
            blocker = self._open_from(low)
            if blocker > high:
                self._decide(i, rec, False)
            else:
                self._wait(blocker, i)
        if len(recs) > self._tidy_at:
            self._tidy()

    def put(self, u: int, v) -> None:
        """The operand's value at record ``u`` is ``v`` (True, False, or None at the end)."""
        if u < self.base:
            return  # every output whose window holds it is decided
        rec = self.recs[u - self.base]
        rec[_VAL] = v
        if v is True:
            self._groups.pop(u, None)  # its waiting outputs are true now
            if not self.past:
                self._decide_range(rec[_FIRST], rec[_LAST], True)
            elif u <= self.high:  # (a younger one is seen when it enters the windows)
                if u > self.last_true:
                    self.last_true = u
                last = rec[_LAST]
                self._decide_range(rec[_FIRST], self.newest if last is None else last, True)
        elif v is False:
            self._false[u] = u + 1
            group = self._groups.pop(u, None)
            if group is not None:
                self._move(group, u)

    def finish(self) -> None:
        """The end of the trace: every operand value is in; what is still open is
        inconclusive."""
        self._decide_range(self.oldest, self.newest, None)

    # ------------------------------------------------------------------ deciding
    def _close(self, j: int, high: int) -> None:
        """Future output ``j``'s window is complete: its last record is ``high``."""
        rec = self.recs[j - self.base]
        rec[_HI] = high
        if rec[_DONE]:
            return
        low = rec[_LO]
        if low is None or low > high:
            self._decide(j, rec, False)  # no record in the window
            return
        blocker = self._open_from(low)
        if blocker > high:
            self._decide(j, rec, False)
        else:
            self._wait(blocker, j)

    def _wait(self, blocker: int, j: int) -> None:
        # blockers grow with the outputs: a new waiting output joins the last group or opens one
        group = self._groups.get(blocker)
        if group is None:
            self._groups[blocker] = [j, j]
        else:
            group[1] = j

    def _move(self, group: list[int], u: int) -> None:
        """Blocker ``u`` turned out false: the group's outputs whose windows end before the
        next value not known false are false; the others wait on that one."""
        first, last = group
        blocker = self._open_from(u)
        recs, base = self.recs, self.base
        j = self._undecided_from(max(first, self.oldest))
        while j <= last and recs[j - base][_HI] < blocker:
            self._decide(j, recs[j - base], False)
            j = self._undecided_from(j + 1)
        if j <= last:
            _wait_on(self._groups, blocker, j, last)

    def _decide_range(self, first: int, last: int, value) -> None:
        recs, base = self.recs, self.base
        j = self._undecided_from(max(first, self.oldest))
        while j <= last:
            self._decide(j, recs[j - base], value)
            j = self._undecided_from(j + 1)

    def _decide(self, j: int, rec: list, value) -> None:
        rec[_DONE] = True
        self._done[j] = j + 1
        self.out.append((j, rec[_T], rec[_NS], value))

    # ------------------------------------------------------------------ union-find
    def _undecided_from(self, j: int) -> int:
        """The first output at or after ``j`` not decided yet (``j`` at least ``oldest``)."""
        return _find(self._done, j)

    def _open_from(self, p: int) -> int:
        """The first record at or after ``p`` whose value is not known to be false."""
        return _find(self._false, max(p, self.base))

    def _tidy(self) -> None:
        """Forget the records no undecided output can need any more."""
        oldest = self.oldest = self._undecided_from(self.oldest)
        if self.past:
            target = min(oldest, self.high + 1)
            if self.b != INF:
                target = min(target, self.low)
            if oldest <= self.newest:
                low = self.recs[oldest - self.base][_LO]
            elif self.b == INF and self.last_true >= self.low:
                low = target  # every window to come holds that true value: no record needed
            else:
                low = self.low
            # the values before the first one not known false in the oldest window are false
            target = min(target, self._open_from(low))
        else:
            target = min(oldest, self.closing)
        drop = target - self.base
        if drop > 0:
            for k in range(self.base, target):
                self._done.pop(k, None)
                self._false.pop(k, None)
            del self.recs[:drop]
            self.base = target
        # looked at again once the records held have doubled: amortised O(1) per record,
        # and never more than twice the records still needed
        self._tidy_at = max(self.TIDY, 2 * len(self.recs))


class FutureOr:
    """``eventually[a,b] v`` of a value decided in any order, as :class:`WindowOr` decides
    it (the same outputs, at the same records), with less work per record; or of ``not v``
    (``hit`` False), its output negated once :meth:`negate` is called: ``always[a,b] v`` is
    ``not eventually[a,b] not v`` without a pass over each value to negate it.

    :meth:`step` each record, in order, with the operand's values decided at it;
    :meth:`finish` at the end. A :class:`~rasm.properties.streams.Source`: decided values
    go to ``out`` as ``(index, time, ns, value)``, in any order.

    * A value ``hit`` (true) at u decides the outputs whose window holds u: a range of
      outputs known when u arrived. Where such values come in record order (the common
      case) the outputs of the range not decided yet are those after the last one's range;
      otherwise they are found by a walk that skips decided outputs through links
      (union–find).
    * A complete window is decided the other way once its values are all known to miss.
      Windows complete in record order and their starts only move on, so one pointer
      (``scan``) walks the values once, stopping at the first one not known to miss: the
      window is decided if that lies beyond it; if not, the window waits on that value (its
      *blocker*), in a group of outputs that moves on as a whole when the blocker turns out
      to miss.

    What it knows of each record is kept in lists side by side, indexed by the record's
    index less ``base``: no object per record for the garbage collector to walk.
    """

    TIDY = 256  # records held before the first look for ones to forget
    ordered = False  # (Source.ordered) its values come in any order

    def __init__(self, a: int, b: int, hit: bool = True) -> None:
        self.a, self.b = a, b
        self.hit, self.miss = hit, not hit  # the operand values that decide, and the others
        self.value = True  # the output where a value in the window hits
        # record base + k: its time as given and in ns, the operand's value there (UNKNOWN
        # until it comes), the first output whose window holds it (known, and appended,
        # when its step ends), whether its output is decided; with a > 0, the first record
        # of its window (None: none yet) and the last output whose window holds it (a = 0:
        # the record itself, both)
        self.times: list = []
        self.nss: list[int] = []
        self.vals: list = []
        self.firsts: list[int | None] = []
        self.done: list[bool] = []
        self.lows: list[int | None] = []
        self.lasts: list[int] = []
        self.base = 0
        self.out: deque = deque()
        # outputs before `reach` have a complete window (it ends before the newest record),
        # those before `opening` know where it starts
        self.opening = self.reach = 0
        self.scan = 0  # values from the last closed window's start up to it miss
        self.last_true = -1  # the newest record whose hit decided its range
        self.covered = -1  # the last output of that range
        self._highs: dict[int, int] = {}  # a waiting output -> the last record in its window
        self._groups: dict[int, list[int]] = {}  # blocker -> [first, last] waiting output
        self._done: dict[int, int] = {}  # decided output -> a later candidate (links)
        self._false: dict[int, int] = {}  # a blocker that turned out to miss -> a later value
        self._tidy_at = self.TIDY

    def negate(self) -> None:
        """Give ``not`` of each output (``not eventually``: a hit decides false)."""
        self.value = not self.value

    def step(self, i: int, t, ns: int, queue: deque) -> None:
        """Record ``i`` at ``ns`` (its time ``t`` as given) arrives; ``queue`` holds the
        operand's values decided at it, ``(index, time, ns, value)``. Its values go in
        before the windows it completes are looked at (fewer of them wait).

        (The first record sets the window up; the next ones go straight to
        :meth:`_step`, which replaces this one.)"""
        self.base = self.opening = self.reach = self.scan = i
        self.step = self._step
        self._step(i, t, ns, queue)

    def _step(self, i: int, t, ns: int, queue: deque) -> None:
        base, nss, vals, groups, a = self.base, self.nss, self.vals, self._groups, self.a
        self.times.append(t)
        nss.append(ns)
        vals.append(UNKNOWN)
        self.done.append(False)
        if a:
            lows = self.lows
            lows.append(None)
            j = self.opening
            while j <= i and ns - nss[j - base] >= a:
                lows[j - base] = i  # output j's window starts here
                j += 1
            self.opening = j
            self.lasts.append(j - 1)
        miss = self.miss
        while queue:
            u, _, _, v = queue.popleft()
            if v is miss and (not groups or u not in groups):  # (no output waits on it)
                if u >= base:
                    vals[u - base] = v
            else:
                self.put(u, v)
        # the windows this record completes (they end before it): decided, or waiting
        j, b, high = self.reach, self.b, i - 1
        scan, done = self.scan, self.done
        while ns - nss[j - base] > b:  # stops at i at the latest
            if not done[j - base]:
                low = self.lows[j - base] if a else j
                if low is not None:
                    if scan < low:
                        scan = low
                    while scan <= high and vals[scan - base] is miss:
                        scan += 1
                if low is None or scan > high:  # every value in the window misses
                    done[j - base] = True
                    self.out.append((j, self.times[j - base], nss[j - base], not self.value))
                else:  # a value in the window not known yet: it waits on it
                    self._highs[j] = high
                    group = groups.get(scan)
                    if group is None:
                        groups[scan] = [j, j]
                    else:
                        group[1] = j
            j += 1
        self.scan = scan
        # this record lies in the windows of outputs reach .. its last
        self.reach = j
        self.firsts.append(j)
        if len(nss) > self._tidy_at:
            self._tidy()

    def put(self, u: int, v) -> None:
        """The operand's value at record ``u`` is ``v`` (True, False, or None at the end)."""
        base = self.base
        if u < base:
            return  # every output whose window holds it is decided
        self.vals[u - base] = v
        if v is self.hit:
            if self._groups:
                self._groups.pop(u, None)  # its waiting outputs are decided now
            k = u - base
            if k < len(self.firsts):
                first = self.firsts[k]
            else:  # the newest record: the windows it completes do not hold it
                first, ns, b, nss = self.reach, self.nss[u - base], self.b, self.nss
                while ns - nss[first - base] > b:
                    first += 1
            self._true(u, first, self.lasts[u - base] if self.a else u)
        elif v is self.miss and self._groups:
            group = self._groups.pop(u, None)
            if group is not None:
                self._move(group, u)

    def finish(self, queue: deque) -> None:
        """The end of the trace: the operand's last values (``queue``) are in; what is still
        open is inconclusive."""
        while queue:
            u, _, _, v = queue.popleft()
            self.put(u, v)
        base, done = self.base, self.done
        for j in range(base, base + len(done)):
            self._decide(j, None)

    # ------------------------------------------------------------------ deciding
    def _decide(self, j: int, value) -> None:
        """Output ``j`` is ``value``, unless it is decided already."""
        k = j - self.base
        if not self.done[k]:
            self.done[k] = True
            self.out.append((j, self.times[k], self.nss[k], value))

    def _true(self, u: int, first: int, last: int) -> None:
        """A hit at ``u``: the outputs ``first`` .. ``last`` not decided yet are decided."""
        base, value = self.base, self.value
        if u > self.last_true:
            # the outputs up to `covered` from `first` on are in the last true value's range
            self.last_true = u
            j = max(first, self.covered + 1, base)
            if last > self.covered:
                self.covered = last
            while j <= last:
                self._decide(j, value)
                j += 1
            return
        j = self._undecided_from(max(first, base))
        while j <= last:
            self._decide(j, value)
            j = self._undecided_from(j + 1)

    def _move(self, group: list[int], u: int) -> None:
        """Blocker ``u`` turned out to miss: the group's outputs whose windows end before the
        next value not known to miss are decided; the others wait on that one."""
        first, last = group
        base, vals, miss, highs = self.base, self.vals, self.miss, self._highs
        j = self._undecided_from(max(first, base))
        if j > last:
            return  # decided meanwhile (a true value in their windows)
        limit = highs[last]
        links = self._false
        p = u + 1
        while p <= limit and vals[p - base] is miss:
            p = links.get(p, p + 1)
        links[u] = p  # the values from u to before p miss
        # j is not decided: decide it, then go on to the next output not decided yet
        # (the one after it, unless that was decided early)
        done, out, times, nss, value = self.done, self.out, self.times, self.nss, not self.value
        while j <= last and highs[j] < p:
            done[j - base] = True
            out.append((j, times[j - base], nss[j - base], value))
            j += 1
            if j - base < len(done) and done[j - base]:
                j = self._undecided_from(j)
        if j <= last:
            _wait_on(self._groups, p, j, last)

    def _undecided_from(self, j: int) -> int:
        """The first output at or after ``j`` not decided yet (the next record's if none); the
        decided ones on the way link to it."""
        base, done, links = self.base, self.done, self._done
        newest = base + len(done) - 1
        path = []
        while j <= newest and done[j - base]:
            path.append(j)
            j = links.get(j, j + 1)
        for k in path:
            links[k] = j
        return j

    def _tidy(self) -> None:
        """Forget the records no undecided output can need any more: those before the
        oldest undecided output (its window, and every later one's, starts at it or after)."""
        base, done, links = self.base, self.done, self._done
        # (the windows still to close read their records: an output decided early keeps
        # them until its window closes)
        target, reach = base, self.reach
        while target < reach and done[target - base]:
            target = links.get(target, target + 1)
        target = min(target, reach)
        drop = target - base
        if drop > 0:
            if self._done:
                self._done = {k: v for k, v in self._done.items() if k >= target}
            if self._false:
                self._false = {k: v for k, v in self._false.items() if k >= target}
            if self._highs:
                self._highs = {k: v for k, v in self._highs.items() if k >= target}
            for column in (self.times, self.nss, self.vals, self.firsts, self.done):
                del column[:drop]
            if self.a:
                del self.lows[:drop]
                del self.lasts[:drop]
            self.base = target
            if self.scan < target:
                self.scan = target
        # looked at again once the records held have doubled: amortised O(1) per record,
        # and never more than twice the records still needed
        self._tidy_at = max(self.TIDY, 2 * len(self.nss))


def _find(links: dict[int, int], j: int) -> int:
    """The end of ``j``'s chain of links, each link on the way made to point at it."""
    root = j
    while root in links:
        root = links[root]
    while j != root:
        links[j], j = root, links[j]
    return root


# --------------------------------------------------------------------------- since and until


class _Chain:
    """Unbounded ``l since r`` (``forward``) or ``l until r`` over values decided in any
    order, by its recurrence: ``Y(x) = r(x) or (l(x) and Y(x - 1))``, false before the first
    record; ``X(x) = r(x) or (l(x) and X(x + 1))``, unknown after the newest record. A value
    decided at x may decide its neighbour's in turn (x + 1 forward, x - 1 backward): each is
    decided once, and appended to ``decided`` as ``(x, value)``."""

    def __init__(self, forward: bool) -> None:
        self.forward = forward
        self.left: dict[int, object] = {}
        self.right: dict[int, object] = {}
        self.value: dict[int, object] = {}
        self.first = self.floor = None
        self.newest = -1
        self.undecided = 0  # forward: the first record whose value is not decided yet
        self.decided: list[tuple[int, object]] = []

    def record(self, i: int) -> None:
        if self.first is None:
            self.first = self.floor = self.undecided = i
        self.newest = i

    def put_left(self, x: int, v) -> None:
        if x >= self.floor:
            self.left[x] = v
            self._settle(x)

    def put_right(self, x: int, v) -> None:
        if x >= self.floor:
            self.right[x] = v
            self._settle(x)

    def _settle(self, x: int) -> None:
        value, step = self.value, 1 if self.forward else -1
        while self.floor <= x <= self.newest and x not in value:
            r = self.right.get(x, UNKNOWN)
            left = self.left.get(x, UNKNOWN)
            if self.forward:
                n = value.get(x - 1, UNKNOWN) if x > self.first else False
            else:
                n = value.get(x + 1, UNKNOWN)
            if r is True or (left is True and n is True):
                v = True
            elif r is False and (left is False or n is False):
                v = False
            else:
                return
            value[x] = v
            self.decided.append((x, v))
            x += step
        if self.forward:
            while self.undecided in value:
                self.undecided += 1

    def finish(self) -> None:
        """Every value is in (None: inconclusive): settle the rest in Kleene's logic."""
        order = range(self.floor, self.newest + 1)
        for x in order if self.forward else reversed(order):
            if x in self.value:
                continue
            if self.forward:
                n = self.value.get(x - 1) if x > self.first else False
            else:
                n = self.value.get(x + 1)  # None after the newest record
            v = k_or(self.right.get(x), k_and((self.left.get(x), n)))
            self.value[x] = v
            self.decided.append((x, v))

    def forget_before(self, x: int) -> None:
        """Records before ``x`` are needed no more."""
        for k in range(self.floor, x):
            self.left.pop(k, None)
            self.right.pop(k, None)
            self.value.pop(k, None)
        self.floor = max(self.floor, x)


class _Conjunction:
    """The three parts of each record's value, and-ed as they come (one false decides)."""

    def __init__(self, parts: int) -> None:
        self.parts = parts
        self.pending: dict[int, list] = {}  # undecided record -> [t, ns, known, value…]
        self.oldest = 0  # no undecided record before it
        self.out: deque = deque()

    def add(self, i: int, t, ns: int, *known) -> None:
        if not self.pending:
            self.oldest = i
        self.pending[i] = [t, ns, len(known), *known, *[UNKNOWN] * (self.parts - len(known))]

    def give(self, i: int, slot: int, v) -> None:
        entry = self.pending.get(i)
        if entry is None or entry[3 + slot] is not UNKNOWN:
            return
        if v is False:
            del self.pending[i]
            self.out.append((i, entry[0], entry[1], False))
            return
        entry[3 + slot] = v
        entry[2] += 1
        if entry[2] == self.parts:
            del self.pending[i]
            self.out.append((i, entry[0], entry[1], k_and(entry[3:])))

    def undecided_from(self, newest: int) -> int:
        """The oldest undecided record (``newest + 1`` if none)."""
        pending = self.pending
        while self.oldest <= newest and self.oldest not in pending:
            self.oldest += 1
        return self.oldest


class UntilWindow:
    """``l until[a,b] r`` of values decided in any order.

    By the identity ``l until[a,b] r = always[0,a) l and X(lo) and eventually[a,b] r``, where
    lo is the first record at least a after i and X the unbounded ``l until r`` — it holds in
    Kleene's three-valued logic too (both sides are the same lattice polynomial in the values),
    so each part can be decided on its own, as early as it can: ``always[0,a) l`` as a window
    (:class:`WindowOr` of ``not l``), ``eventually[a,b] r`` as one, X by its recurrence.
    """

    def __init__(self, a: int, b: int) -> None:
        self.a = a
        self.within = WindowOr(False, a, b)
        self.before = WindowOr(False, 0, a - 1) if a > 0 else None
        self.chain = _Chain(forward=False)
        self.value = _Conjunction(3)
        self.out = self.value.out
        self.starting: deque = deque()  # (record, ns) whose window has no first record yet
        self.waiting: dict[int, list[int]] = {}  # x -> the records whose X is X(x)
        self.newest = -1

    def record(self, i: int, t, ns: int) -> None:
        self.within.record(i, t, ns)
        self.chain.record(i)
        self.newest = i
        if self.before is None:  # a = 0: record i's X is X(i)
            self.value.add(i, t, ns, True)
            return
        self.before.record(i, t, ns)
        self.value.add(i, t, ns)
        starting = self.starting
        while starting and ns - starting[0][1] >= self.a:  # their windows start here
            self.waiting.setdefault(i, []).append(starting.popleft()[0])
        starting.append((i, ns))

    def put_left(self, x: int, v) -> None:
        if self.before is not None:
            self.before.put(x, k_not(v))
        self.chain.put_left(x, v)

    def put_right(self, x: int, v) -> None:
        self.within.put(x, v)
        self.chain.put_right(x, v)

    def settle(self) -> None:
        """Pass on what the parts decided (after the values of a record)."""
        give = self.value.give
        out = self.within.out
        while out:
            j, _, _, v = out.popleft()
            give(j, 2, v)
        if self.before is not None:
            out = self.before.out
            while out:
                j, _, _, v = out.popleft()
                give(j, 0, k_not(v))
        decided = self.chain.decided
        if decided:
            if self.before is None:
                for x, v in decided:
                    give(x, 1, v)
            else:
                waiting = self.waiting
                for x, v in decided:
                    for j in waiting.pop(x, ()):
                        give(j, 1, v)
            decided.clear()
        oldest = self.value.undecided_from(self.newest)
        chain = self.chain
        if oldest - chain.floor > BATCH:  # forgotten in batches: amortised O(1) per record
            for k in range(chain.floor, oldest):
                self.waiting.pop(k, None)
            chain.forget_before(oldest)

    def finish(self) -> None:
        self.within.finish()
        if self.before is not None:
            self.before.finish()
        self.chain.finish()
        self.settle()
        for j, _ in self.starting:  # their window never started: X there is inconclusive
            self.value.give(j, 1, None)
        self.starting.clear()


class SinceWindow:
    """``l since[a,b] r`` of values decided in any order.

    By the identity ``l since[a,b] r = historically[0,a) l and Y(hi) and once[a,b] r``, where
    hi is the last record at least a before i and Y the unbounded ``l since r`` (see
    :class:`UntilWindow`).
    """

    def __init__(self, a: int, b: int | float) -> None:
        self.a = a
        self.within = WindowOr(True, a, b)
        self.after = WindowOr(True, 0, a - 1) if a > 0 else None
        self.chain = _Chain(forward=True)
        self.value = _Conjunction(3)
        self.out = self.value.out
        self.young: deque = deque()  # (record, ns) less than a old
        self.high: int | None = None  # the last record at least a old
        self.waiting: dict[int, list[int]] = {}  # x -> the records whose Y is Y(x)
        self.newest = -1

    def record(self, i: int, t, ns: int) -> None:
        self.within.record(i, t, ns)
        self.chain.record(i)
        self.newest = i
        if self.after is None:
            self.value.add(i, t, ns, True)
        else:
            self.after.record(i, t, ns)
            self.value.add(i, t, ns)
        young = self.young
        young.append((i, ns))
        while young and ns - young[0][1] >= self.a:
            self.high = young.popleft()[0]
        high = self.high
        if high is None:
            self.value.give(i, 1, False)  # no record old enough: nothing to look back to
            return
        if high in self.chain.value:
            self.value.give(i, 1, self.chain.value[high])
        else:
            self.waiting.setdefault(high, []).append(i)

    def put_left(self, x: int, v) -> None:
        if self.after is not None:
            self.after.put(x, k_not(v))
        self.chain.put_left(x, v)

    def put_right(self, x: int, v) -> None:
        self.within.put(x, v)
        self.chain.put_right(x, v)

    def settle(self) -> None:
        give = self.value.give
        out = self.within.out
        while out:
            j, _, _, v = out.popleft()
            give(j, 2, v)
        if self.after is not None:
            out = self.after.out
            while out:
                j, _, _, v = out.popleft()
                give(j, 0, k_not(v))
        decided = self.chain.decided
        if decided:
            waiting = self.waiting
            for x, v in decided:
                for j in waiting.pop(x, ()):
                    give(j, 1, v)
            decided.clear()
        if self.high is None:
            return
        # Y is still needed just before its first value not decided yet (the next one builds
        # on it; a record waiting for Y waits for one of those) and where the records to come
        # look (at `high` or later)
        chain = self.chain
        need = min(self.high, chain.undecided - 1)
        if need - chain.floor > BATCH:  # forgotten in batches: amortised O(1) per record
            for k in range(chain.floor, need):
                self.waiting.pop(k, None)
            chain.forget_before(need)

    def finish(self) -> None:
        self.within.finish()
        if self.after is not None:
            self.after.finish()
        self.chain.finish()
        self.settle()
