"""Trials of several experiments that share their history, simulated once up to where they part.

A trial with a warm-up is the same trial without one, continued (`engine`): trial j of
`breakdown` spends its 18,000 s warm-up exactly as trial j of `initial_distribution`
spends its whole run, with the same seed, and parts from it only when its robot breaks
down. Such trials form a tree: a stretch of history shared by every trial below it, then
one branch for each different thing that happens next (an event, or nothing), and at a
trial's end its record. Simulating the tree, each stretch once, computes every trial
exactly as it would be computed alone (a test compares them bit for bit), for less work:
a branch goes on from a copy of the whole simulation, made by forking the process.

Two trials can share history only if everything that acts before they part is the same:
arena, robot, team, learner, values, time step, physics, seed, controller and, for a
baseline that starts late, its start (`lineage`).
Their warm-ups, durations and events may differ; the events decide where they part. A trial
that ends with a number of deliveries counts them from the end of its warm-up, and may end
before its duration: it shares history only with trials of the same warm-up, duration and
delivery count.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from tavc_cli.experiments import clock
from tavc_cli.experiments.spec import TrialSpec
from tavc_cli.experiments.trial import clock_events


@dataclass(frozen=True, eq=False)
class Item:
    """A trial to compute and the results folder its record goes to (each one its own,
    compared by identity)."""

    spec: TrialSpec
    folder: Path


def lineage(spec: TrialSpec) -> str:
    """What must be equal for two trials to share history, as a digest: the spec without its
    warm-up, duration and events (the tree sorts those out), or only without its events for a
    trial that ends with a number of deliveries."""
    if spec.deliveries is not None:
        return replace(spec, breakdowns=(), value_changes=()).key()
    return replace(spec, duration_s=0.0, warmup_s=0.0, breakdowns=(), value_changes=()).key()


def end_tick(spec: TrialSpec) -> int:
    """The tick at which the trial ends (after its warm-up and duration)."""
    return clock.end_tick(spec.t0_s, spec.duration_s, spec.dt_s)


def events_at(spec: TrialSpec, tick: int) -> tuple:
    """What happens to the trial at `tick`: its events that fall due then, in firing order."""
    return tuple((kind, ev.robot, ev.circuit) if hasattr(ev, "robot") else (kind, ev.values)
                 for t, kind, ev in clock_events(spec) if clock.due_tick(t, spec.dt_s) == tick)


def _next_event_tick(spec: TrialSpec, after: int) -> int | None:
    ticks = [k for k in (clock.due_tick(t, spec.dt_s) for t, _, _ in clock_events(spec)) if k > after]
    return min(ticks) if ticks else None


@dataclass
class Node:
    """A stretch [start, end) of ticks that the trials below it share: `specs` holds, for
    each trial of the batch, one trial going through it (its events up to `end` are those of
    every trial below); at `end` the trials in `ends` are recorded and each of `children`
    goes on as its own branch."""

    start: int
    end: int
    specs: tuple[TrialSpec, ...]
    ends: list[tuple[Item, ...]] = field(default_factory=list)
    children: list[Node] = field(default_factory=list)

    @property
    def ticks(self) -> int:
        """Ticks simulated in this node and below it, for one trial of the batch."""
        return self.end - self.start + sum(c.ticks for c in self.children)

    def items(self) -> list[tuple[Item, ...]]:
        """Every trial recorded in this node or below it."""
        return self.ends + [i for c in self.children for i in c.items()]

    def shape(self) -> tuple:
        """The tree with seeds and trial indices left out: batches of one shape can share a process."""
        return (self.start, self.end, tuple(_plain(s) for s in self.specs),
                tuple(tuple((_plain(i.spec), i.folder) for i in end) for end in self.ends),
                tuple(c.shape() for c in self.children))


def _plain(spec: TrialSpec) -> str:
    return replace(spec, trial=0, seed=()).key()


def _grow(items: list[Item], start: int) -> Node:
    """The tree of `items`, which share their history up to tick `start` (its events included)."""
    cuts = [end_tick(i.spec) for i in items] + [k for i in items if (k := _next_event_tick(i.spec, start))]
    end = min(cuts)
    node = Node(start, end, (items[0].spec,))
    going = [i for i in items if end_tick(i.spec) > end]
    node.ends = [(i,) for i in items if end_tick(i.spec) == end]
    for group in _part(going, end):
        node.children.append(_grow(group, end))
    return node


def _part(items: list[Item], tick: int) -> list[list[Item]]:
    """Items grouped by what happens to them at `tick`, in the order they first appear."""
    groups: dict[tuple, list[Item]] = {}
    for i in items:
        groups.setdefault(events_at(i.spec, tick), []).append(i)
    return list(groups.values())


def trees(items: list[Item]) -> list[Node]:
    """One tree for each set of items that share a beginning (the same lineage, and the same
    events at tick 0), each tree for one trial."""
    by_lineage: dict[str, list[Item]] = {}
    for i in items:
        by_lineage.setdefault(lineage(i.spec), []).append(i)
    return [_grow(group, 0) for same in by_lineage.values() for group in _part(same, 0)]


def zip_trees(nodes: list[Node]) -> Node:
    """Trees of one shape (one per trial) as one tree whose nodes hold every trial's spec."""
    first = nodes[0]
    return Node(first.start, first.end, tuple(s for n in nodes for s in n.specs),
                [tuple(i for n in nodes for i in n.ends[k]) for k in range(len(first.ends))],
                [zip_trees([n.children[k] for n in nodes]) for k in range(len(first.children))])


def prune(node: Node, pending: set[Item]) -> Node | None:
    """A tree of one trial (before `zip_trees`) cut to what `pending` needs: branches with
    nothing pending dropped, records of trials already done left out. None if nothing below
    is pending."""
    children = [c for c in (prune(c, pending) for c in node.children) if c is not None]
    ends = [e for e in node.ends if any(i in pending for i in e)]
    if not children and not ends:
        return None
    ends = [tuple(i for i in e if i in pending) for e in ends]
    return Node(node.start, node.end, node.specs, ends, children)


@dataclass(frozen=True)
class TreeBatch:
    """Trials of one shape of tree advanced together in one process, forking where they part."""

    controller: str
    index: int
    root: Node
    dt_s: float

    @property
    def specs(self) -> tuple[TrialSpec, ...]:
        """The trials the batch starts as."""
        return self.root.specs

    @property
    def sim_seconds(self) -> float:
        """Simulated seconds of work, summed over the batch's trials."""
        return self.root.ticks * self.dt_s * len(self.root.specs)


def plan(items: list[Item], pending: set[Item], size: int, workers: int = 1) -> list[TreeBatch]:
    """Tree batches that compute every pending item: trees grown over all `items` (a trial
    already done may still be the trunk of a pending one), grouped by shape into batches of at
    most `size` trials, and small enough that `workers` processes all get one when there are
    trials enough; stretches that no pending item needs are left out."""
    by_shape: dict[tuple, list[Node]] = {}
    for tree in trees(items):
        cut = prune(tree, pending)
        if cut is not None:
            by_shape.setdefault(cut.shape(), []).append(cut)
    n_trees = sum(len(v) for v in by_shape.values())
    size = max(1, min(size, -(-n_trees // max(1, workers))))
    out: list[TreeBatch] = []
    for group in by_shape.values():
        for k in range(0, len(group), size):
            root = zip_trees(group[k:k + size])
            out.append(TreeBatch(root.specs[0].controller, len(out), root, root.specs[0].dt_s))
    # the most work first, so that the last batches to start are short
    return sorted(out, key=lambda b: -b.sim_seconds)
