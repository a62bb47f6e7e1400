"""Small inputs with huge costs are refused early, with the number in the message (issue #13)."""
from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest
from PIL import Image

from softpipe.light import images
from softpipe.light.images import texture_bytes
from softpipe.light.texture import Texture2D


def _png_header_only(path, width: int, height: int) -> None:
    """A PNG whose header claims width × height (8-bit gray); its pixel data is a stub."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 16))
                     + chunk(b"IEND", b""))


def test_a_9000_squared_png_is_refused_before_decoding_with_the_estimate(tmp_path):
    path = tmp_path / "big.png"
    Image.new("L", (9000, 9000), 128).save(path)           # a few kilobytes on disk
    assert path.stat().st_size < 200_000
    need = texture_bytes(9000, 9000)
    assert need == 9000 * 9000 * images.PEAK_BYTES_PER_TEXEL
    with pytest.raises(ValueError, match=r"big\.png' is 9000×9000 texels, which needs about 8\.3 GiB .* limit of "
                                         r"2\.0 GiB"):
        Texture2D(path)


def test_the_limit_is_per_texture_and_global(tmp_path, monkeypatch):
    path = tmp_path / "small.png"
    Image.new("RGB", (64, 32), (10, 20, 30)).save(path)
    assert Texture2D(path).width == 64
    with pytest.raises(ValueError, match=r"64×32 texels.*max_bytes"):
        Texture2D(path, max_bytes=texture_bytes(64, 32) - 1)
    assert Texture2D(path, max_bytes=texture_bytes(64, 32)).height == 32
    monkeypatch.setattr(images, "MAX_TEXTURE_BYTES", 1000)
    with pytest.raises(ValueError, match="limit of 0.0 GiB"):
        Texture2D(path)
    with pytest.raises(ValueError, match=r"array of shape \(32, 64, 3\)"):
        Texture2D(np.zeros((32, 64, 3), np.uint8))


def test_a_decompression_bomb_is_a_softpipe_error_not_pillows(tmp_path):
    path = tmp_path / "bomb.png"
    _png_header_only(path, 40000, 40000)                   # past Pillow's own limit: refused on opening
    with pytest.raises(ValueError, match=r"Texture2D: image file '.*bomb\.png' is too large to decode safely") as e:
        Texture2D(path)
    assert e.value.__cause__ is None and e.value.__suppress_context__


# ---------------------------------------------------------------- draws too large for the machine

def _triangles(n: int, size: float = 0.01):
    rng = np.random.default_rng(1)
    centres = np.repeat(rng.uniform(-0.9, 0.9, (n, 4)) * [1, 1, 0.5, 0], 3, axis=0)
    pos = centres + rng.uniform(-size, size, (3 * n, 4)) * [1, 1, 1, 0]
    pos[:, 3] = 1.0
    return pos, {"color": rng.random((3 * n, 3))}


def test_a_draw_whose_triangles_cannot_fit_fails_before_assembly_with_the_estimate(monkeypatch):
    import softpipe as sp
    from softpipe.core import runtime as _runtime
    pos, varyings = _triangles(10_000)
    fb = sp.Framebuffer(64, 64)
    before = fb.samples_color.copy()
    monkeypatch.setattr(_runtime, "CHECK_MEMORY_FROM", 0)      # small numbers here, checked all the same
    monkeypatch.setattr(_runtime, "available_memory", lambda: 1 << 20)
    with pytest.raises(MemoryError, match=r"drawing 10,000 triangles \(assembly and triangle setup, 232 bytes "
                                          r"each\) needs about 0\.0 GiB, and this machine has 0\.0 GiB available"):
        sp.draw(fb, pos, varyings=varyings)
    assert np.array_equal(fb.samples_color, before)          # nothing was drawn
    monkeypatch.setattr(_runtime, "available_memory", lambda: 10_000 * 232)
    sp.draw(fb, pos, varyings=varyings)                       # exactly enough: drawn
    assert not np.array_equal(fb.samples_color, before)


def test_a_trace_too_large_for_memory_fails_before_it_keeps_the_fragments(monkeypatch):
    import softpipe as sp
    from softpipe.core import runtime as _runtime
    from softpipe.pipeline import draw as pipeline
    pos, varyings = _triangles(20, size=0.5)
    fb = sp.Framebuffer(64, 64)
    covered = int(sp.DrawCall(sp.Framebuffer(64, 64), pos, varyings=varyings, path="reference").run(trace=True)
                  .fragments.__len__())
    need = covered * pipeline.BYTES_PER_TRACED_FRAGMENT
    monkeypatch.setattr(_runtime, "CHECK_MEMORY_FROM", 0)
    assert covered > 1000 and need > 20 * 232                 # the trace, not the triangles, is what is too large
    monkeypatch.setattr(_runtime, "available_memory", lambda: need - 1)
    with pytest.raises(MemoryError, match=rf"tracing {covered:,} fragments"):
        sp.draw(fb, pos, varyings=varyings, trace=True)
    monkeypatch.setattr(_runtime, "available_memory", lambda: need)
    assert len(sp.draw(fb, pos, varyings=varyings, trace=True)) == covered


def test_small_needs_are_not_checked_at_all(monkeypatch):
    from softpipe.core import runtime as _runtime
    asked = []
    monkeypatch.setattr(_runtime, "available_memory", lambda: asked.append(1) or 0)
    _runtime.check_memory("a small draw", _runtime.CHECK_MEMORY_FROM - 1)
    assert not asked
    with pytest.raises(MemoryError, match="a large draw needs about 0.1 GiB"):
        _runtime.check_memory("a large draw", _runtime.CHECK_MEMORY_FROM)
