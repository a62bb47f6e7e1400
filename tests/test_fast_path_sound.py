"""The fast path is never wrong (issue #13): a differential test of the two paths.

Shaders that discard in many spellings (the name DISCARD, an alias, a closure
variable, ``float("nan")``, ``math.nan``, ``np.nan``, a helper returning it, a
NaN made at run time, a NaN uniform or varying alpha), shaders that raise
mid-draw, on framebuffers of at least 128×128 samples so that ``path="auto"``
would take the fast path: "auto" gives the reference path's bytes, or the same
error with the framebuffer unchanged. A NaN alpha the analysis does not see is
caught while the fast path shades, and the draw is done again on the reference
path from the saved depth.
"""
import math

import numpy as np
import pytest
from conftest import window_to_clip

import softpipe as sp
from softpipe.language import kernels
from softpipe.pipeline.draw import DrawCall
from softpipe.pipeline.sampling import rotated_grid_4x
from softpipe.pipeline.visibility import FAST_PATH_MIN_SAMPLES

W, H = 160, 128
assert W * H >= FAST_PATH_MIN_SAMPLES

KILL = sp.DISCARD                    # an alias
NOTHING = math.nan                   # a NaN number under another name
NAN_COLOR = (0.0, 0.0, 0.0, float("nan"))


def by_name(v, u, frag):
    return sp.DISCARD if frag.x < u.cut else (v.color[0], v.color[1], v.color[2], 1.0)


def by_alias(v, u, frag):
    if frag.x < u.cut:
        return KILL
    return (v.color[0], v.color[1], v.color[2], 1.0)


def _closure():
    gone = sp.DISCARD

    def by_closure(v, u, frag):
        if frag.y < u.cut * 0.8:
            return gone
        return (v.color[0], v.color[1], 0.25, 1.0)
    return by_closure


by_closure = _closure()


def float_nan(v, u, frag):
    return (v.color[0], v.color[1], v.color[2], float("nan") if frag.x + frag.y < u.cut * 1.5 else 1.0)


def math_nan(v, u, frag):
    a = 1.0
    if frag.x > u.cut:
        a = math.nan
    return (v.color[0], 0.5, v.color[2], a)


def np_nan(v, u, frag):
    return (v.color[0], v.color[1], v.color[2], np.nan if frag.y > u.cut * 0.6 else 0.75)


def veil():
    return (0.0, 0.0, 0.0, NOTHING)


def by_helper(v, u, frag):
    if frag.x < u.cut:
        return veil()
    return (v.color[0], v.color[1], v.color[2], 1.0)


def made_at_run_time(v, u, frag):
    big = (frag.x - u.cut) * 1e308 * 1e308         # +inf right of the cut
    return (v.color[0], v.color[1], v.color[2], big - big if frag.x > u.cut else 1.0)


def uniform_alpha(v, u, frag):
    return (v.color[0], v.color[1], v.color[2], u.alpha if frag.x < u.cut else 1.0)


def global_tuple(v, u, frag):
    return NAN_COLOR if frag.y < u.cut else (v.color[0], v.color[1], v.color[2], 1.0)


def raising(v, u, frag):
    if frag.x > u.cut:
        raise ValueError("the shader gave up")
    return (v.color[0], v.color[1], v.color[2], 1.0)


DISCARDING = [by_name, by_alias, by_closure, float_nan, math_nan, np_nan, by_helper, global_tuple]
#: Shaders whose NaN alpha no reading of the code can see: only the run-time check catches them.
UNSEEN = [made_at_run_time, uniform_alpha]


def scene(seed):
    """Random overlapping triangles at random depths, with a full-screen quad in front of part of them."""
    rng = np.random.default_rng(seed)
    n = 40
    pts = np.round(rng.uniform(-20, [W + 20, H + 20], (3 * n, 2)) * 4) / 4
    z = np.repeat(rng.uniform(-0.9, 0.9, n), 3)[:, None] + rng.uniform(-0.05, 0.05, (3 * n, 1))
    quad = np.array([[0, 0], [W, 0], [W, H], [0, 0], [W, H], [0, H]], float)
    pts = np.r_[pts, quad]
    z = np.r_[z, np.full((6, 1), rng.uniform(-0.2, 0.6))]
    clip = window_to_clip(np.c_[pts, z], W, H)
    colors = rng.uniform(0, 1, (len(clip), 3))
    return clip, colors


def framebuffer(pattern, record=False):
    """A framebuffer already holding a picture and depths (an earlier draw), and with ``record`` a
    visibility record of it."""
    fb = sp.Framebuffer(W, H, pattern=pattern, record=record)
    fb.clear((0.1, 0.2, 0.3, 1.0), depth=0.9)
    clip = window_to_clip(np.c_[[(0, 0), (W, 0), (0, H)], np.full(3, 0.5)], W, H)
    sp.draw(fb, clip, varyings={"color": np.array([[0.9, 0.1, 0.1]] * 3)}, path="reference")
    return fb


def run(path, shader, seed, pattern=sp.CENTER, shading="sample", uniforms=None, colors=None, record=False):
    clip, rgb = scene(seed)
    fb = framebuffer(pattern, record)
    before = fb.samples_color.tobytes(), fb.samples_depth.tobytes()
    call = DrawCall(fb, clip, varyings={"color": rgb if colors is None else colors}, fragment_shader=shader,
                    uniforms=uniforms or {"cut": 70.0, "alpha": math.nan}, path=path,
                    sample_shading=shading)
    error = None
    try:
        call.run()
    except Exception as e:      # noqa: BLE001  (compared between the paths below)
        error = e
    return fb, before, call, error


def same_bytes(a, b):
    """The same color and depth, and the same visibility record if they keep one."""
    return (a.samples_color.tobytes() == b.samples_color.tobytes()
            and a.samples_depth.tobytes() == b.samples_depth.tobytes()
            and (a.record is None) == (b.record is None) and (a.record is None or a.record.tobytes() == b.record.tobytes()))


CASES = [(sp.CENTER, "sample"), (rotated_grid_4x(), "center")]


@pytest.mark.parametrize("pattern,shading", CASES, ids=["1x", "4x-center"])
@pytest.mark.parametrize("shader", DISCARDING + UNSEEN, ids=lambda f: f.__name__)
def test_auto_gives_the_reference_bytes_for_a_shader_that_discards(shader, pattern, shading):
    for seed in (1, 2):
        ref, _, ref_call, ref_error = run("reference", shader, seed, pattern, shading)
        auto, before, call, error = run("auto", shader, seed, pattern, shading)
        assert ref_error is None and error is None, (ref_error, error)
        assert call.path_taken == "reference", call.path_reason
        assert same_bytes(ref, auto), f"{shader.__name__}: the paths differ ({call.path_reason})"
        assert ref.samples_color.tobytes() != before[0]            # the draw drew something
        assert not np.isnan(ref.samples_color[..., 3]).any()          # and no NaN alpha was written


@pytest.mark.parametrize("shader", DISCARDING, ids=lambda f: f.__name__)
def test_the_analysis_sees_every_spelling_of_discard(shader):
    assert kernels.may_discard(shader)


@pytest.mark.parametrize("shader", UNSEEN, ids=lambda f: f.__name__)
def test_a_nan_alpha_the_analysis_misses_is_caught_while_shading(shader):
    assert not kernels.may_discard(shader)
    ref, *_ = run("reference", shader, 3)
    for path in ("auto", "fast"):         # even path="fast": drawn again on the reference path
        fb, _, call, error = run(path, shader, 3)
        assert error is None and call.path_taken == "reference" and "NaN alpha" in call.path_reason
        assert same_bytes(ref, fb)
    # a shader that happens to return no NaN keeps the fast path
    fast, _, call, _ = run("auto", shader, 3, uniforms={"cut": 1e9, "alpha": 0.5})
    ref, *_ = run("reference", shader, 3, uniforms={"cut": 1e9, "alpha": 0.5})
    assert call.path_taken == "fast" and same_bytes(ref, fast)


def test_a_nan_alpha_in_the_varyings_of_the_default_shader():
    """The default shader of an RGBA color varying passes a NaN alpha through (the audit's 19,837 px)."""
    clip, rgb = scene(4)
    alpha = np.where(np.arange(len(clip)) % 7 == 0, np.nan, 1.0)[:, None]
    rgba = np.c_[rgb, alpha]
    ref, *_ = run("reference", None, 4, colors=rgba)
    auto, _, call, error = run("auto", None, 4, colors=rgba)
    assert error is None and call.path_taken == "reference"
    assert same_bytes(ref, auto)


@pytest.mark.parametrize("pattern,shading", CASES, ids=["1x", "4x-center"])
@pytest.mark.parametrize("cut", [-1.0, 40.0, 150.0])
def test_a_shader_that_raises_leaves_the_framebuffer_unchanged_on_both_paths(cut, pattern, shading):
    results = {}
    for path in ("reference", "auto", "fast"):
        fb, before, call, error = run(path, raising, 5, pattern, shading, uniforms={"cut": cut, "alpha": 1.0})
        assert isinstance(error, sp.ShaderError), error
        assert "raised ValueError: the shader gave up" in str(error)
        assert (fb.samples_color.tobytes(), fb.samples_depth.tobytes()) == before, path
        results[path] = type(error), str(error).split(",")[0]
    assert len(set(results.values())) == 1


@pytest.mark.parametrize("pattern,shading", CASES, ids=["1x", "4x-center"])
def test_the_visibility_record_is_the_reference_paths_and_put_back_when_shading_fails(pattern, shading):
    """The visibility record of the fast path is the reference path's; a draw whose shader raises
    leaves the record as it was, and one whose alpha is NaN (drawn again on the reference path) leaves
    the reference path's record."""
    ref, *_ = run("reference", raising, 5, pattern, shading, uniforms={"cut": 1e9, "alpha": 1.0}, record=True)
    fast, _, call, error = run("auto", raising, 5, pattern, shading, uniforms={"cut": 1e9, "alpha": 1.0}, record=True)
    assert error is None and call.path_taken == "fast", call.path_reason
    assert same_bytes(ref, fast) and (fast.record > 0).sum() > 100     # the draw's values (the first draw's are 0)
    for cut in (-1.0, 40.0, 150.0):
        fb, _, call, error = run("auto", raising, 5, pattern, shading, uniforms={"cut": cut, "alpha": 1.0},
                                 record=True)
        assert isinstance(error, sp.ShaderError) and call.path_taken == "fast"
        assert fb.record.tobytes() == framebuffer(pattern, record=True).record.tobytes(), cut
    for shader in UNSEEN:              # a NaN alpha met while shading: drawn again on the reference path
        ref, *_ = run("reference", shader, 3, pattern, shading, record=True)
        fb, _, call, error = run("auto", shader, 3, pattern, shading, record=True)
        assert error is None and call.path_taken == "reference" and "NaN alpha" in call.path_reason
        assert same_bytes(ref, fb), shader.__name__


@pytest.mark.parametrize("pattern,shading", CASES, ids=["1x", "4x-center"])
def test_a_fast_draws_record_values_wait_until_the_record_is_read_or_written_again(pattern, shading):
    """A fast-path draw's record values are stored when the record is next read (fb.record) or written
    (the next draw), not before (Framebuffer.defer_visible); whenever it is read it is the reference path's."""
    ref, fast = framebuffer(pattern, record=True), framebuffer(pattern, record=True)
    after = []
    for seed in (1, 2, 3):
        clip, rgb = scene(seed)
        DrawCall(ref, clip, varyings={"color": rgb}, path="reference", sample_shading=shading).run()
        after.append(ref.record.copy())
        call = DrawCall(fast, clip, varyings={"color": rgb}, path="fast", sample_shading=shading)
        call.run()
        assert call.path_taken == "fast", call.path_reason
        stored, _, deferred = fast.record_parts()
        assert deferred is not None                              # this draw's values wait
        # what is stored is the record before this draw: the one drawn before, stored when this one came
        before = after[-2] if len(after) > 1 else framebuffer(pattern, record=True).record
        assert stored.tobytes() == before.tobytes(), seed
    assert same_bytes(ref, fast)                                 # read: stored now
    assert fast.record_parts()[2] is None and (fast.record != after[1]).any()


def test_a_clear_forgets_a_waiting_draw_and_sets_a_record_written_by_hand_to_minus_one():
    fb = sp.Framebuffer(W, H, record=True)
    clip, rgb = scene(1)
    sp.draw(fb, clip, varyings={"color": rgb}, path="fast")
    assert fb.record_parts()[2] is not None
    fb.clear()
    stored, blank, deferred = fb.record_parts()
    assert deferred is None and blank and (stored == -1).all()
    # an array handed out may be written after the clear: the next clear sets it again, whatever was drawn
    record = fb.record
    record[0, 5, 7] = 42
    fb.clear()
    assert (fb.record == -1).all()


def test_a_framebuffer_pickled_with_a_waiting_draw_carries_its_record():
    import pickle
    fb = sp.Framebuffer(W, H, record=True)
    clip, rgb = scene(2)
    sp.draw(fb, clip, varyings={"color": rgb}, path="fast")
    assert fb.record_parts()[2] is not None
    copy = pickle.loads(pickle.dumps(fb))
    assert copy.record.tobytes() == fb.record.tobytes() and (copy.record >= 0).sum() > 1000


@pytest.mark.parametrize("seed", [6, 7])
def test_random_thresholds_same_bytes_or_same_error(seed):
    """Random cuts and alphas for every shader: same bytes, or the same error and the framebuffer unchanged."""
    rng = np.random.default_rng(seed)
    for shader in DISCARDING + UNSEEN + [raising]:
        uniforms = {"cut": float(rng.uniform(-20, W + 20)), "alpha": float(rng.choice([math.nan, 0.5]))}
        ref, ref_before, _, ref_error = run("reference", shader, seed, uniforms=uniforms)
        auto, before, _, error = run("auto", shader, seed, uniforms=uniforms)
        assert type(ref_error) is type(error), (shader.__name__, ref_error, error)
        assert same_bytes(ref, auto), shader.__name__
        if error is not None:
            assert (auto.samples_color.tobytes(), auto.samples_depth.tobytes()) == before


def test_a_shader_that_raises_in_a_later_batch_leaves_the_framebuffer_unchanged(monkeypatch):
    """The reference path merges batch by batch: an error in a later batch undoes the earlier ones."""
    import softpipe.pipeline.draw as pipeline
    monkeypatch.setattr(pipeline, "MAX_FRAGMENTS_PER_BATCH", 3000)
    fb, before, call, error = run("reference", raising, 5, uniforms={"cut": 150.0, "alpha": 1.0})
    assert isinstance(error, sp.ShaderError)
    assert (fb.samples_color.tobytes(), fb.samples_depth.tobytes()) == before


def test_the_built_in_programs_still_take_the_fast_path():
    """The analysis must not send softpipe's own shaders (which matter for speed) to the reference path."""
    import importlib
    import pkgutil

    import softpipe.programs
    from softpipe.pipeline.fragment import color_rgb, color_rgba
    from softpipe.pipeline.merge_state import MergeState
    from softpipe.pipeline.visibility import fast_path_blocker
    found = [color_rgb, color_rgba]
    for info in pkgutil.iter_modules(softpipe.programs.__path__):
        module = importlib.import_module(f"softpipe.programs.{info.name}")
        found += [f for name, f in vars(module).items() if name.endswith("_fragment") and callable(f)
                  and getattr(f, "__module__", None) == module.__name__]
    assert len(found) > 8
    for shader in found:
        assert fast_path_blocker(MergeState(), shader) is None, shader
    # nothing to keep for the default RGB shader; a shader that raises keeps the colors it overwrites
    assert not kernels.may_raise(color_rgb) and kernels.alpha_is_finite(color_rgb)
    assert kernels.may_raise(raising) and not kernels.may_raise(by_alias)
