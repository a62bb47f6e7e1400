"""The arrays a BVH is made of: the sizes and the child code the build and the traversal share.

A BVH is kept twice (docs/raytracing.md, "The BVH", has the whole story):

- **the binary tree**, flattened depth first (pbrt's LinearBVHNode): node 0 is the root, an
  inner node's left child is the next node and ``first[node]`` its right child, a leaf's
  triangles are ``order[first : first + count]``. This is the BVH's definition: its
  invariants are tested and :meth:`~softpipe.rays.bvh.BVH.refit` works on it.
- **the traversal's tree**, collapsed from it: wide nodes of up to :data:`WIDTH` children,
  their boxes side by side in float32, each child coded as one int64 ``ref << REF_SHIFT | n``
  (n = 0: wide node ref; n > 0: a leaf of n triangles from triangle block ref), and the
  leaves' triangles in blocks of :data:`BLOCK`.

:mod:`softpipe.rays.build` makes both, :mod:`softpipe.rays.traverse` walks the second;
this module is what they agree on.
"""
from __future__ import annotations

__all__ = ["MAX_DEPTH", "WIDTH", "BLOCK", "REF_SHIFT", "COUNT_MASK"]

#: The traversal's stack holds one pending node per level: the build keeps every
#: leaf's depth below this (root at depth 0).
MAX_DEPTH = 64

#: Children of a traversal node (a "wide" node): the binary tree is collapsed into nodes
#: of up to this many children, whose boxes are tested together.
WIDTH = 4

#: Triangles are tested in blocks of this many (a leaf's triangles fill one or more blocks).
BLOCK = 4

#: A wide node's child (and an entry of the traversal's stack) is one int64, ``ref << REF_SHIFT | n``:
#: ``code >> REF_SHIFT`` is ref, ``code & COUNT_MASK`` is n.
REF_SHIFT = 32
COUNT_MASK = (1 << 32) - 1
