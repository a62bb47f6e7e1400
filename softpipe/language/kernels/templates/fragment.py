"""Template of the fragment loops: the generator (kernels/generate.py) copies these functions.

- ``interpolate``: the varyings, FragInfo (and derivatives) at barycentrics of a triangle.
- ``fragment_inputs``: those of fragment i of the reference path's batch.
- ``inputs_loop``: those of many fragments, the varyings and ``point_coord`` written to
  arrays (the explorer page's, softpipe/views/explorer.py); the shader is not run.
- ``fragment_loop``: the reference path: the shader once per fragment row.
- ``visible_loop``: the fast path: the shader once per sample the visibility pass kept
  (``visible_loop_at_samples`` is this loop with ``shading`` 0).
- ``primitive_loop``: the fast path's points and lines: the shader once per sample their
  visibility pass kept, in primitive order (in a module of its own, kernels/generate.py's
  ``primitive_kernel``; ``LINES`` says which).
- ``fragment_loop_outputs``: ``fragment_loop`` for a framebuffer of several attachments
  (multiple render targets), generated only for one: the shader returns one value per
  attachment. Both paths run it (the fast path on the visible samples' fragments).

How a template becomes code (full-line comments left out, ``if`` on constants
decided, placeholders in capitals filled): kernels/template.py.

Constants: ``SMOOTH`` (a varying is interpolated perspective-correct),
``DERIVATIVES`` (the shader takes ``derivatives``). Placeholders, filled per
varying layout (the expressions come from templates/varyings.py):

- ``VARYINGS_AT_BARYCENTRICS``: a line per varying, ``v_color = (…)  # smooth``.
- ``VARYING_VALUES``: ``v_color, v_uv`` (``0.0`` for a layout without varyings).
- ``STORE_VARYINGS``: a line per component of the Varyings, in order, to its column
  (``out_varyings[r, 3] = v[1][0]  # uv.x``; ``v[0]``, the one field ``none``, for a layout without varyings).
- ``DERIVATIVES_X``, ``DERIVATIVES_Y``: ``dqx = …`` (when ``SMOOTH``) and a line per
  varying, ``dx_color = (…)``; ``DX_VALUES``, ``DY_VALUES``: ``dx_color, dx_uv``.
- ``OUTPUT_FORMATS``: the attachments as text, ``'color:rgba8,id:r32i'`` (what ``outputs`` checks);
  ``STORE_OUTPUTS``: a line per component of each value, to its attachment's array
  (``out_more[1][i] = values[2]  # id``).
"""


# Stand-ins for what the generated module's header defines or imports (kernels/generate.py: the shader,
# JIT, the Varyings namedtuple, the contract's FragInfo and Derivatives, the kernels package's
# borrowed_tuple and rgba, the triangle setup's per-sample functions), so that a linter, or an
# import, can read this file; the generator copies only the functions.
def JIT(function):
    return function


shader = Varyings = FragInfo = Derivatives = borrowed_tuple = rgba = outputs = None
pixel_coverage = shading_point = sample_depth = finite_rgba = None
point_sample_inputs = line_sample_inputs = sample_means = LINES = None
SMOOTH = DERIVATIVES = None
VARYINGS_AT_BARYCENTRICS = VARYING_VALUES = DERIVATIVES_X = DERIVATIVES_Y = DX_VALUES = DY_VALUES = None
STORE_VARYINGS = OUTPUT_FORMATS = STORE_OUTPUTS = None


@JIT
def interpolate(t, b0, b1, b2, fx, fy, z, inv_w, corner, front, prim_id, bary_grad):
    """The varyings and FragInfo at barycentrics (b0, b1, b2) of triangle t."""
    if SMOOTH:
        # perspective-correct weights: b_k / w_k, renormalized
        q0 = b0 * inv_w[t, 0]
        q1 = b1 * inv_w[t, 1]
        q2 = b2 * inv_w[t, 2]
        qs = q0 + q1 + q2
        if not qs > 0.0:
            # an extrapolated pixel centre (multisampling) can make it 0
            q0, q1, q2, qs = b0, b1, b2, 1.0
        # v = (Σ q_k v_k) · (1/qs): one division a fragment, which the sums need not wait for
        # (q_k/qs per weight put three divisions in front of every sum)
        r = 1.0 / qs
    VARYINGS_AT_BARYCENTRICS(t, b0, b1, b2, q0, q1, q2, r, corner)
    varyings = Varyings(VARYING_VALUES)
    frag = FragInfo(fx, fy, z, front[t], prim_id[t], (b1, b2))
    if DERIVATIVES:
        # the screen-space derivatives of every varying, from the barycentrics' gradients
        if not SMOOTH:
            qs = 1.0
        DERIVATIVES_X(t, bary_grad, inv_w, corner, qs)
        dx = Varyings(DX_VALUES)
        DERIVATIVES_Y(t, bary_grad, inv_w, corner, qs)
        dy = Varyings(DY_VALUES)
        return varyings, frag, Derivatives(dx, dy)
    else:
        return varyings, frag


@JIT
def fragment_inputs(i, triangle, frag_x, frag_y, depth, bary, inv_w, corner, front, prim_id, bary_grad):
    """The varyings and FragInfo of fragment i, exactly as the shader receives them."""
    return interpolate(triangle[i], bary[i, 0], bary[i, 1], bary[i, 2], frag_x[i], frag_y[i], depth[i],
                       inv_w, corner, front, prim_id, bary_grad)


@JIT
def inputs_loop(rows, triangle, frag_x, frag_y, depth, bary, inv_w, corner, front, prim_id, bary_grad,
                out_varyings, out_point_coord):
    """The varyings and point_coord of fragments rows[r], exactly as the shader receives them, in row r
    of out_varyings (the Varyings' components in order, a column each) and of out_point_coord."""
    for r in range(rows.shape[0]):
        if DERIVATIVES:
            v, frag, derivatives = fragment_inputs(rows[r], triangle, frag_x, frag_y, depth, bary, inv_w, corner, front, prim_id, bary_grad)
        else:
            v, frag = fragment_inputs(rows[r], triangle, frag_x, frag_y, depth, bary, inv_w, corner, front, prim_id, bary_grad)
        STORE_VARYINGS(r, v, out_varyings)
        out_point_coord[r, 0] = frag.point_coord[0]
        out_point_coord[r, 1] = frag.point_coord[1]


@JIT
def fragment_loop(triangle, frag_x, frag_y, depth, bary, inv_w, corner, front, prim_id, bary_grad, uniforms, out_color):
    # borrowed once, before the first fragment: numba counts no references to the arrays in them
    uniforms = borrowed_tuple(uniforms)
    for i in range(triangle.shape[0]):
        if DERIVATIVES:
            varyings, frag, derivatives = fragment_inputs(i, triangle, frag_x, frag_y, depth, bary, inv_w, corner, front, prim_id, bary_grad)
            c = rgba(shader(varyings, uniforms, frag, derivatives))
        else:
            varyings, frag = fragment_inputs(i, triangle, frag_x, frag_y, depth, bary, inv_w, corner, front, prim_id, bary_grad)
            c = rgba(shader(varyings, uniforms, frag))
        out_color[i, 0] = c[0]
        out_color[i, 1] = c[1]
        out_color[i, 2] = c[2]
        out_color[i, 3] = c[3]


@JIT
def fragment_loop_outputs(triangle, frag_x, frag_y, depth, bary, inv_w, corner, front, prim_id, bary_grad, uniforms,
                          out_color, out_more):
    """fragment_loop for a framebuffer of several attachments: the shader's values, one per attachment
    (checked by ``outputs``), to out_color (location 0) and out_more's arrays (the others, in order)."""
    uniforms = borrowed_tuple(uniforms)
    for i in range(triangle.shape[0]):
        if DERIVATIVES:
            varyings, frag, derivatives = fragment_inputs(i, triangle, frag_x, frag_y, depth, bary, inv_w, corner, front, prim_id, bary_grad)
            values = outputs(shader(varyings, uniforms, frag, derivatives), OUTPUT_FORMATS)
        else:
            varyings, frag = fragment_inputs(i, triangle, frag_x, frag_y, depth, bary, inv_w, corner, front, prim_id, bary_grad)
            values = outputs(shader(varyings, uniforms, frag), OUTPUT_FORMATS)
        STORE_OUTPUTS(i, values, out_color, out_more)


@JIT
def visible_loop(row_lo, row_hi, vis, touched, tile_w, tile_h, edges, bias, plane, offsets, positions,
                 shading, inv_w, corner, front, prim_id, bary_grad, uniforms, out_color, saved_color, started, status):
    """Shade the samples the visibility pass kept (softpipe/pipeline/visibility.py), image rows row_lo:row_hi.

    ``visible_loop_at_samples`` is this loop for ``shading`` 0 alone (each visible sample
    shaded at itself): without the multisampling branches its first compile is shorter
    (benchmarks/README.md), and a draw that shades at the samples compiles only it.

    Barycentrics, depth and position come from the triangle setup's functions (softpipe/pipeline/setup.py), as
    the rasterizer's do. Tiles no triangle touched are skipped; each sample is shaded on its
    own, so the order (tile, sample, column) does not change a byte.

    ``shading`` 1 or 2 (multisampling at the pixel centre or at the centroid): a triangle is
    shaded once per pixel, as the rasterizer's run of its samples there is, with the depth
    of the first sample it covers (visible or not); its other visible samples copy the color.

    So that a draw that fails leaves the framebuffer as it was (visibility.shade_visible):
    before a row is shaded, the colors its visible samples hold are copied to saved_color
    (unless it is empty) and started[row] is set; a NaN alpha (DISCARD, which the reference
    path discards) is not written: status[0] = 1 and every band stops at its next row
    (the row under way writes no copy of a color it may not have written).

    status[1 + row] counts the samples of image row ``row`` written with a NaN or infinite
    color (:func:`~softpipe.language.kernels.diagnostics.finite_rgba`), so that the draw can say so.
    """
    samples, height, width = vis.shape[0], vis.shape[1], vis.shape[2]
    save = saved_color.shape[0] > 0
    uniforms = borrowed_tuple(uniforms)
    for row in range(row_lo, row_hi):
        if status[0] != 0:
            return
        j = height - 1 - row
        if save:
            for tile_x in range(touched.shape[1]):
                if touched[j // tile_h, tile_x]:
                    for s in range(samples):
                        for i in range(tile_x * tile_w, min(tile_x * tile_w + tile_w, width)):
                            if vis[s, row, i] >= 0:
                                for c in range(4):
                                    saved_color[s, row, i, c] = out_color[s, row, i, c]
            started[row] = True
        for tile_x in range(touched.shape[1]):
            if not touched[j // tile_h, tile_x]:
                continue
            for s in range(samples):
                for i in range(tile_x * tile_w, min(tile_x * tile_w + tile_w, width)):
                    t = vis[s, row, i]
                    if t < 0:
                        continue
                    if shading == 0:           # at the sample
                        mask, depth_sample, count = 0, s, 1
                    else:                      # multisampling: once per pixel and triangle
                        earlier = -1
                        for m in range(s):
                            if vis[m, row, i] == t:
                                earlier = m
                                break
                        if earlier >= 0:
                            if status[0] != 0:       # (its color may not have been written)
                                continue
                            for c in range(4):
                                out_color[s, row, i, c] = out_color[earlier, row, i, c]
                            if status[1 + row] and not finite_rgba(out_color, s, row, i):
                                status[1 + row] += 1
                            continue
                        mask, depth_sample, count = pixel_coverage(edges, bias, t, i, j, offsets)
                    b0, b1, b2, fx, fy = shading_point(edges, plane, t, i, j, s, mask, count, offsets,
                                                       positions, shading)
                    z = sample_depth(edges, plane, t, i, j, depth_sample, offsets)
                    if DERIVATIVES:
                        varyings, frag, derivatives = interpolate(t, b0, b1, b2, fx, fy, z, inv_w, corner, front, prim_id, bary_grad)
                        c = rgba(shader(varyings, uniforms, frag, derivatives))
                    else:
                        varyings, frag = interpolate(t, b0, b1, b2, fx, fy, z, inv_w, corner, front, prim_id, bary_grad)
                        c = rgba(shader(varyings, uniforms, frag))
                    if c[3] == c[3]:
                        out_color[s, row, i, 0] = c[0]
                        out_color[s, row, i, 1] = c[1]
                        out_color[s, row, i, 2] = c[2]
                        out_color[s, row, i, 3] = c[3]
                        if not finite_rgba(out_color, s, row, i):     # NaN or infinity written: counted per row
                            status[1 + row] += 1
                    else:                      # NaN alpha: the reference path discards it
                        status[0] = 1


@JIT
def primitive_loop(lo, hi, keys, tri, run, setup_a, setup_b, setup_c, offsets, positions, shading, inv_w, corner,
                   front, prim_id, bary_grad, uniforms, out_color, bad):
    """Shade the visible samples lo:hi of points or lines (``keys``, ``tri``: sorted by primitive,
    softpipe/pipeline/visibility.py), writing each color into out_color; bad[lo] is 1 if one was written
    NaN or infinite (a flag a band: the array is as long as the samples).

    Each sample's inputs are computed here, from the primitive's setup (``setup_a``, ``setup_b``,
    ``setup_c``: a point's centre, size and depth, or a line's ends, width and depths) by the
    functions the reference path's fragments are made with (softpipe/pipeline/points.py:
    point_sample_inputs; lines.py: line_sample_inputs, ``run`` the place of a wide line's
    fragment in its run), rather than written to arrays and read back. Each sample is shaded on
    its own, so the bands do not change a byte. Only for a shader proved not to fail (no raise, a
    finite alpha): nothing is kept to put back.
    """
    samples, height, width = out_color.shape[0], out_color.shape[1], out_color.shape[2]
    uniforms = borrowed_tuple(uniforms)
    # borrowed too: handed to interpolate and the setup's functions at every sample, each array's
    # references were counted there (an atomic add and subtract, on counts both threads share)
    keys, tri, run, setup_a, setup_b, setup_c, offsets, positions, inv_w, corner, front, prim_id, bary_grad, out_color = borrowed_tuple(
        (keys, tri, run, setup_a, setup_b, setup_c, offsets, positions, inv_w, corner, front, prim_id, bary_grad, out_color))
    means = sample_means(offsets, positions)
    n_bad = 0
    for k in range(lo, hi):
        key, t = keys[k], tri[k]
        # the key's (row, sample, column) with one integer division (two with multisampling), not
        # three: a 64-bit division is tens of cycles, a good part of a sample's shading
        if samples == 1:
            row = key // width
            s = 0
            i = key - row * width
        else:
            place = key // width
            i = key - place * width
            row = place // samples
            s = place - row * samples
        j = height - 1 - row
        if LINES:
            b0, b1, b2, fx, fy, z = line_sample_inputs(setup_a, setup_c, run, t, i, j, s, row, offsets, positions, shading, means)
        else:
            b0, b1, b2, fx, fy, z = point_sample_inputs(setup_a, setup_b, setup_c, t, i, j, s, positions, shading, means)
        if DERIVATIVES:
            varyings, frag, derivatives = interpolate(t, b0, b1, b2, fx, fy, z, inv_w, corner, front, prim_id, bary_grad)
            c = rgba(shader(varyings, uniforms, frag, derivatives))
        else:
            varyings, frag = interpolate(t, b0, b1, b2, fx, fy, z, inv_w, corner, front, prim_id, bary_grad)
            c = rgba(shader(varyings, uniforms, frag))
        out_color[s, row, i, 0] = c[0]
        out_color[s, row, i, 1] = c[1]
        out_color[s, row, i, 2] = c[2]
        out_color[s, row, i, 3] = c[3]
        if not finite_rgba(out_color, s, row, i):
            n_bad += 1
    bad[lo] = 1 if n_bad > 0 else 0
