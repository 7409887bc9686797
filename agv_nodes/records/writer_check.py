"""Who may write an input topic: the named writer's one endpoint, learnt from the ROS graph.

ROS-free (the graph is a `lookup` function), shared by every record reader and the stop switches
(agv_nodes/ros_ports.py). See `WriterCheck` and `SwitchInput`.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable
import time
from typing import Any

FOREIGN_WRITER = 'foreign_writer'  # the rejection reason of a record from another endpoint
DUPLICATE_WRITER = 'duplicate_writer'  # ... of a record from either of two live named writers
# What the graph says of an endpoint whose node it has not learnt yet (rmw_dds_common).
UNKNOWN_NODE = '_NODE_NAME_UNKNOWN_'
GID_PREFIX = 'gid:'  # a writer named by its endpoint's GID (or its participant's, a prefix)


def node_name(name: str) -> str:
    """Return a node's full name with one leading '/' (the graph's bare-DDS names have none)."""
    return '/' + name.strip('/')


def gid_writer(writer: str) -> str | None:
    """Return the hex digits of a `gid:<hex>` writer (None for a node name)."""
    if not writer.startswith(GID_PREFIX):
        return None
    return writer[len(GID_PREFIX):].lower()


class WriterCheck:
    """Which DDS endpoint may write one record topic, learnt from the graph as samples come.

    `lookup()` returns the topic's writers as the graph shows them: (node's full name, endpoint
    GID). It is asked only when a sample comes from a GID not known yet (or samples wait, or a
    duplicate stands), at most once every `requery_s` (wall, `clock`). An endpoint of node
    `writer` is genuine (names compare with one leading '/'); any other is foreign, and stays so
    (an endpoint's node never changes). A `writer` of the form `gid:<hex>` names the endpoint
    itself: a GID that starts with those digits (all 16 bytes: one writer; the first 12: every
    writer of one DDS participant) is genuine at once, whatever node the graph shows for it (a
    plain DDS writer has none). The graph may know a sample's writer before it knows that
    writer's node, or not at all yet (discovery lag), so such a sample is held, not judged:
    released in order once the graph names its node, and foreign while its GID stays unnamed
    past `patience_s` (a plain DDS writer, which has no node), until the graph names it; past
    `hold` waiting samples (a second of the 340 Hz stream) the oldest is rejected.

    A genuine GID other than the one last followed is the writer restarted (its records start
    a new counter): `admit` says 'restart' for its first sample. A sample from a genuine GID that
    was followed before and replaced shows two processes writing as the writer at once (a
    restarted process never sends from its old GID again): a duplicate. From then on every
    sample of either is `duplicate_writer`, until the graph shows only one of them (then its
    next sample is a 'restart').
    """

    def __init__(self, writer: str, lookup: Callable[[], Iterable[tuple[str, bytes]]],
                 clock: Callable[[], float] = time.monotonic, requery_s: float = 0.2,
                 patience_s: float = 2.0, hold: int = 400) -> None:
        self._gid = gid_writer(writer)
        self.writer = writer if self._gid is not None else node_name(writer)
        self._lookup = lookup
        self._clock = clock
        self._requery_s = requery_s
        self._patience_s = patience_s
        self._hold = hold
        self.current: bytes | None = None  # the genuine GID last admitted
        self.genuine: set[bytes] = set()
        self.nodes: dict[bytes, str] = {}  # GID -> node, for every GID the graph has named
        self._unnamed: dict[bytes, float] = {}  # GID -> when first seen unnamed
        self._held: list[tuple[Any, bytes]] = []  # (data, GID), oldest first
        self._asked = float('-inf')
        self._live: set[bytes] = set()  # the topic's writers at the last query
        self._replaced: set[bytes] = set()  # genuine GIDs followed once and then replaced
        self.duplicates: list[bytes] = []  # live genuine GIDs writing at once, first first
        self._resume = False  # a duplicate ended: the one left is taken up afresh
        self.lookups = 0  # graph queries made
        self.held = 0  # samples that waited for the graph to name their writer
        self.restarts = 0
        self.duplicate_samples = 0  # samples rejected as duplicate_writer

    def admit(self, data: Any, gid: bytes) -> list[tuple[Any, bytes, str]]:
        """Take one sample; return the samples now decided, oldest first.

        Each as (data, GID, verdict); `data` is the caller's, passed through. The verdict is
        'genuine', 'restart' (the genuine writer under a new GID), 'foreign_writer' or
        'duplicate_writer'.
        """
        out: list[tuple[Any, bytes, str]] = []
        if self._gid is not None and gid not in self.genuine and gid.hex().startswith(self._gid):
            self.genuine.add(gid)  # named by its GID: no need to wait for the graph
        if (gid not in self.nodes or self._held or self.duplicates) and self._refresh():
            if self.duplicates:
                self._end_duplicate()
            if self._held:
                out += self._release()
        if gid in self.nodes or gid in self.genuine or self._expired(gid):
            out.append(self._decided(data, gid))
            return out
        self.held += 1
        self._held.append((data, gid))
        if len(self._held) > self._hold:  # a flood from endpoints the graph does not name
            oldest, who = self._held.pop(0)
            out.append((oldest, who, FOREIGN_WRITER))
        return out

    def names(self, node: str, gid: bytes) -> bool:
        """Return True when an endpoint of `node` with `gid` is the named writer."""
        if self._gid is not None:
            return gid.hex().startswith(self._gid)
        return node_name(node) == self.writer

    def name(self, gid: bytes) -> str:
        """Return `gid`'s node as the graph names it ('?' where it does not)."""
        return self.nodes.get(gid, '?')

    def _refresh(self) -> bool:
        now = self._clock()
        if now - self._asked < self._requery_s:
            return False
        self._asked = now
        self.lookups += 1
        self._live = set()
        for node, gid in self._lookup():
            self._live.add(gid)
            if node.rsplit('/', 1)[-1] != UNKNOWN_NODE:
                self.nodes[gid] = node_name(node)
                if self._gid is None and node_name(node) == self.writer:
                    self.genuine.add(gid)
        return True

    def _end_duplicate(self) -> None:
        left = [gid for gid in self.duplicates if gid in self._live]
        if len(left) <= 1:  # the others left the graph: the one that stays is the writer
            self._replaced.update(self.duplicates)
            self._replaced.difference_update(left)
            self.duplicates = []
            self.current = left[0] if left else None
            self._resume = True

    def _expired(self, gid: bytes) -> bool:
        # Not cached as foreign: a loaded machine can take longer than the patience to name a
        # genuine writer, whose records must then be taken as soon as the graph names it.
        first = self._unnamed.setdefault(gid, self._clock())
        return self._clock() - first >= self._patience_s

    def _release(self) -> list[tuple[Any, bytes, str]]:
        out, waiting = [], []
        for data, gid in self._held:
            if gid in self.nodes or gid in self.genuine or self._expired(gid):
                out.append(self._decided(data, gid))
            else:
                waiting.append((data, gid))
        self._held = waiting
        return out

    def _decided(self, data: Any, gid: bytes) -> tuple[Any, bytes, str]:
        if gid in self.nodes:
            self._unnamed.pop(gid, None)
        if gid not in self.genuine:
            return data, gid, FOREIGN_WRITER
        current = self.current
        if self.duplicates or (gid in self._replaced and current is not None
                               and gid != current):
            # Both write: neither is followed. A third genuine GID joins the duplicate.
            if not self.duplicates:
                self.duplicates = [gid, current]  # type: ignore[list-item]
            elif gid not in self.duplicates:
                self.duplicates.append(gid)
            self.duplicate_samples += 1
            return data, gid, DUPLICATE_WRITER
        verdict = 'genuine'
        if (current is not None and gid != current) or self._resume:
            verdict = 'restart'
            self.restarts += 1
            if current is not None and current != gid:
                self._replaced.add(current)
            self._replaced.discard(gid)
            self._resume = False
        self.current = gid
        return data, gid, verdict

    def duplicate_text(self, topic: str) -> str:
        """Name the endpoints of a standing duplicate ('' when there is none)."""
        if not self.duplicates:
            return ''
        who = ' and '.join(f'{self.name(gid)} ({gid.hex()})' for gid in self.duplicates)
        return f'{topic}: {len(self.duplicates)} live endpoints write as {self.writer}: {who}'


FOREIGN_STOP = 'foreign_stop_taken'  # a stop (true) from another endpoint: acted on, counted


class CheckedInput:
    """A stream that is no record (a camera's frames) taken through a WriterCheck.

    The named writer's samples are acted on; any other's (foreign, or either of two live
    writers) are refused, counted by reason and the last one named. Read by inputs_report like
    a RecordReader.
    """

    lost = 0  # no counters on such a stream

    def __init__(self, name: str, check: WriterCheck) -> None:
        self.name = name
        self.check = check
        self.accepted = 0
        self.rejects: Counter[str] = Counter()
        self.last_error = ''
        self.last_reason = ''
        self.stamp_ns: int | None = None
        self.duplicate = ''
        self.waiting = ''

    @property
    def rejected(self) -> int:
        """Samples refused (and, for a switch, stops taken from other endpoints)."""
        return sum(self.rejects.values())

    def age_s(self, now_ns: int) -> float:
        """Seconds since the last sample acted on (inf if none yet)."""
        return float('inf') if self.stamp_ns is None else (now_ns - self.stamp_ns) * 1e-9

    def identity(self) -> str:
        """Say whose input this is (its /diagnostics `writer` value)."""
        current = self.check.current
        return f'{self.check.writer} ({current.hex() if current else "not heard yet"})'

    def take(self, data: Any, gid: bytes, now_ns: int) -> list[Any]:
        """Judge one sample from `gid`; return the samples to act on, oldest first."""
        out = []
        for sample, who, verdict in self.check.admit(data, gid):
            self.duplicate = self.check.duplicate_text(self.name)
            if verdict in ('genuine', 'restart'):
                self.accepted += 1
                self.stamp_ns = now_ns
                out.append(sample)
            else:
                self._refused(verdict, who, f'{self.name}: from {self.check.name(who)} '
                              f'({who.hex()}), not the writer {self.check.writer}')
        return out

    def _refused(self, reason: str, who: bytes, text: str) -> None:
        self.rejects[reason] += 1
        self.last_reason = reason
        self.last_error = text


class SwitchInput(CheckedInput):
    """A stop switch (hw/radio_stop, hw/bumper: true = stop) taken through a WriterCheck.

    The named writer's value is acted on. From any other endpoint (foreign, or one of two that
    both write as the writer) a `true` is acted on all the same, since a stop is never refused
    (fail-safe), and counted as `foreign_stop_taken`; a `false` is refused, counted as
    `foreign_writer` (or `duplicate_writer`), and never releases a stop. Only the named writer's
    next `false` does. Read by inputs_report like a RecordReader: accepted, rejects by reason,
    the last foreign sample named, the writer, and ERROR while a duplicate stands.
    """

    def __init__(self, name: str, check: WriterCheck) -> None:
        super().__init__(name, check)
        self.value: bool | None = None  # the value last acted on
        self._seq = 0  # samples taken
        self._last_stop = 0  # the last `true` acted on (its sample number)

    def take(self, on: bool, gid: bytes, now_ns: int) -> list[bool]:
        """Judge one sample from `gid`; return the values to act on, oldest first.

        A `true` is acted on at once, before its writer is judged (the graph may take a while
        to name it); a `false` only once its writer is known to be the named one, and not if a
        `true` sent after it has been acted on meanwhile.
        """
        self._seq += 1
        out = []
        if on:
            self._last_stop = self._seq
            self.value, self.stamp_ns = True, now_ns
            out.append(True)
        for (seq, value), who, verdict in self.check.admit((self._seq, bool(on)), gid):
            self.duplicate = self.check.duplicate_text(self.name)
            if verdict in ('genuine', 'restart'):
                self.accepted += 1
                if not value and seq > self._last_stop:
                    self.value, self.stamp_ns = False, now_ns
                    out.append(False)
                continue
            self._refused(FOREIGN_STOP if value else verdict, who,
                          f'{self.name}: {str(value).lower()} from {self.check.name(who)} '
                          f'({who.hex()}), not the writer {self.check.writer}: '
                          + ('taken (a stop is never refused)' if value else
                             'refused (only the writer releases a stop)'))
        return out
