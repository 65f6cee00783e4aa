"""Physics runs of many controllers from one start, sharing the gait cycles they share.

Controllers sampled from one population often walk the same first cycles from a start (the
same genes meet the same sensors), and a physics run is a function of its start, its servo
noise seed and the gaits it walks. ``PhysicsTree`` keeps one ``PhysicsWorld`` and a tree of
the states it has reached: a node is the state after a sequence of gaits from the start, its
children the states one more cycle of a gait leads to. ``tree.view()`` is a fresh run from the
start (the ``evolve.world.World`` protocol): stepping a gait another view already stepped
from the same node moves to the child without physics; a new gait restores the node's state
(MuJoCo's integration state, the servo-noise generator, the servos' last commands) and runs the
cycle. The results are those of separate runs, bit for bit (``tests/test_shared_physics.py``):
``mj_step`` is a function of the integration state (``mujoco.mjtState.mjSTATE_INTEGRATION``),
and the servo noise is drawn from a generator whose state is restored with it.

Cost: one cycle per node; ≈ 2 kB per node. The 50 behaviours of issue 16's ranking sample
(docs/envelope.md) walk 0.49 of their cycles in distinct nodes. A cycle that raised
``PhysicsError`` raises it again for every view that takes it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from evolve import geometry
from servo_mj.world.physics_world import PhysicsWorld

_STATE = mujoco.mjtState.mjSTATE_INTEGRATION


@dataclass
class _Node:
    """The state after one sequence of gaits from the start."""

    state: np.ndarray
    """MuJoCo's integration state (``mj_getState``)."""
    rng: dict[str, Any]
    """The servo-noise generator's ``bit_generator.state``."""
    servos: tuple[np.ndarray, np.ndarray, int]
    """The robot's last nominal target and command (rad) and its cycle count."""
    pose: tuple[float, float, float]
    children: dict[int, _Node | Exception] = field(default_factory=dict)
    objects: tuple[bool, bool] | None = None
    """Object sensors, read on first demand."""


class PhysicsTree:
    """The states one ``PhysicsWorld`` has reached from its start (module docstring).

    ``world`` must be freshly placed at the start; the tree owns it from then on.
    """

    def __init__(self, world: PhysicsWorld) -> None:
        self.world = world
        self.root = self._snapshot()
        self._at: _Node | None = self.root
        """The node whose state the world holds (None: a failed cycle's)."""
        self.cycles_run = 0
        """Gait cycles simulated (the work done; the views walked at least as many)."""

    def _snapshot(self) -> _Node:
        w, bot = self.world, self.world.bot
        state = np.empty(mujoco.mj_stateSize(w.model, _STATE))
        mujoco.mj_getState(w.model, w.data, state, _STATE)
        return _Node(state, bot.rng.bit_generator.state, bot.servo_state(), w.pose())

    def _go(self, node: _Node) -> None:
        """Put the world in ``node``'s state (nothing to do when it is there)."""
        if self._at is node:
            return
        w, bot = self.world, self.world.bot
        mujoco.mj_setState(w.model, w.data, node.state, _STATE)
        bot.rng.bit_generator.state = node.rng
        bot.set_servo_state(node.servos)
        w.cycles = node.servos[2]
        self._at = node

    def child(self, node: _Node, gait: int) -> _Node:
        """The state one cycle of ``gait`` leads to from ``node`` (run once, then kept)."""
        known = node.children.get(gait)
        if known is None:
            self._go(node)
            try:
                self.world.step(gait)
            except Exception as exc:  # the same cycle fails the same way for every view
                node.children[gait] = exc
                self._at = None
                raise
            self.cycles_run += 1
            known = node.children[gait] = self._snapshot()
            self._at = known
        if isinstance(known, Exception):
            raise known
        return known

    def objects(self, node: _Node) -> tuple[bool, bool]:
        """Object sensors at ``node``."""
        if node.objects is None:
            self._go(node)
            node.objects = self.world.object_sensors()
        return node.objects

    def view(self) -> SharedView:
        """A new run from the start."""
        return SharedView(self)


class SharedView:
    """One run through a ``PhysicsTree``: the ``evolve.world.World`` protocol, as a
    ``PhysicsWorld`` placed at the tree's start would give it."""

    def __init__(self, tree: PhysicsTree) -> None:
        self.tree = tree
        self.node = tree.root

    def pose(self) -> tuple[float, float, float]:
        return self.node.pose

    def step(self, gait: int) -> None:
        self.node = self.tree.child(self.node, int(gait))

    def object_sensors(self) -> tuple[bool, bool]:
        return self.tree.objects(self.node)

    def light_sensors(self) -> tuple[bool, bool]:
        x, y, h = self.node.pose
        return geometry.light_sensors(x, y, h, self.tree.world.world)


__all__ = ["PhysicsTree", "SharedView"]
