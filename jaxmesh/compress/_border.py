"""The cut border of the connectivity coder, one class for encoder and decoder.

The border between decoded and undecoded triangles is a set of oriented loops of
*nodes* (one vertex each) in doubly linked lists.  Each loop has a *gate* node g
(the gate edge runs from g to its successor m) and a length; the loops still
open form a stack whose top is worked on.  Every traversal symbol is one
operation here, so the encoder (which decides the symbol) and the decoder
(which reads it) change the border by the same code:

====  =========================================================================
N     :meth:`insert`: a new node k between g and m
L     :meth:`cut_left`: the node before g closes its fan; the gate moves to it
R     :meth:`cut_right`: the node after m closes its fan
E     :meth:`close`: the loop of three is done
S     :meth:`splice` then :meth:`split`: the loop splits at an existing node
M     :meth:`splice` then :meth:`merge`: another open loop joins this one
====  =========================================================================
"""

from __future__ import annotations

__all__ = ["Border"]


class Border:
    def __init__(self) -> None:
        self.vertex: list[int] = []
        self.next: list[int] = []
        self.prev: list[int] = []
        self.gate: list[int] = []          # per loop id: its gate node
        self.length: dict[int, int] = {}   # per open loop id: its number of nodes
        self.stack: list[int] = []         # the open loops, the current one last

    def add_node(self, v: int) -> int:
        self.vertex.append(v)
        self.next.append(-1)
        self.prev.append(-1)
        return len(self.vertex) - 1

    def link(self, *nodes: int) -> None:
        """Chain nodes: nodes[0] → nodes[1] → … (next and prev pointers)."""
        for x, y in zip(nodes, nodes[1:]):
            self.next[x] = y
            self.prev[y] = x

    def open_loop(self, k0: int, k1: int, k2: int) -> int:
        """A new component's seed triangle k0 → k1 → k2 → k0, gate k0, on top of the stack."""
        self.link(k0, k1, k2, k0)
        loop = len(self.gate)
        self.gate.append(k0)
        self.length[loop] = 3
        self.stack.append(loop)
        return loop

    def current(self) -> tuple[int, int, int]:
        """(loop, gate node g, its successor m) of the loop on top of the stack."""
        lp = self.stack[-1]
        g = self.gate[lp]
        return lp, g, self.next[g]

    def insert(self, lp: int, g: int, k: int, m: int) -> None:
        self.link(g, k, m)
        self.length[lp] += 1

    def cut_left(self, lp: int, k: int, m: int) -> None:
        self.link(k, m)
        self.gate[lp] = k
        self.length[lp] -= 1

    def cut_right(self, lp: int, g: int, k: int) -> None:
        self.link(g, k)
        self.length[lp] -= 1

    def close(self, lp: int) -> None:
        self.stack.pop()
        del self.length[lp]

    def splice(self, j: int, k2: int, m: int, g: int, k: int) -> None:
        """The face (b, a, c) with c an existing node k (j its predecessor) and k2 a
        copy of it: j → k2 → m and g → k."""
        self.link(j, k2, m)
        self.link(g, k)

    def split(self, lp: int, g: int, k2: int, size_a: int, size_b: int, new_is_a: bool) -> int:
        """After :meth:`splice` of a split: part a (from g, ``size_a`` nodes) and part b
        (from k2, ``size_b``); the new loop id goes to a or b.  b stays below a on the
        stack, a is worked on first.  Returns the new loop id."""
        new = len(self.gate)
        loop_a, loop_b = (new, lp) if new_is_a else (lp, new)
        self.gate.append(-1)
        self.gate[loop_a] = g
        self.gate[loop_b] = k2
        self.length[loop_a] = size_a
        self.length[loop_b] = size_b
        self.stack[-1] = loop_b
        self.stack.append(loop_a)
        return new

    def merge(self, lp: int, other: int) -> None:
        """After :meth:`splice` of a merge: ``other`` is now part of ``lp``."""
        self.length[lp] = self.length[lp] + self.length.pop(other) + 1
        self.stack.remove(other)
