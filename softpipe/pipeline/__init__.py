"""The GPU's stages, in pipeline order (docs/design.md draws the diagram):

0. :mod:`.transforms`, :mod:`.camera`: model → world → eye → clip matrices, the viewport
1. :mod:`.vertex`: the vertex shader over every vertex → ``VertexOut``
2. :mod:`.assembly`: topology, clipping, divide, viewport, culling → ``Primitives``
3. :mod:`.setup` (one triangle setup for everything after it), :mod:`.raster` (the
   reference rasterizer) → ``Fragments``
4. :mod:`.fragment`: interpolation and the fragment shader → ``ShadedFragments``
5. :mod:`.output`: the output merger, into the :mod:`.framebuffer`

The fast path is a second back end over the same setup, with its own coverage walk
(:mod:`.tiles`: tiles, row spans, hierarchical depth) and no output merger;
:mod:`.visibility` chooses between the two and shades the visible samples. :mod:`.draw`
wires the stages into a draw call; :mod:`.trace` keeps what each stage made.
:mod:`.sampling` holds the sample patterns the rasterizer and framebuffer share.
A stage imports only stages before it (tests/test_architecture.py checks it).
"""
