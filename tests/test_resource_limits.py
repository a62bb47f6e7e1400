"""Small inputs with huge costs are refused early, with the number in the message (issue #13)."""
from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest
from PIL import Image

from softpipe import texture
from softpipe.texture import Texture2D, texture_bytes


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
    assert need == 9000 * 9000 * texture.PEAK_BYTES_PER_TEXEL
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
    monkeypatch.setattr(texture, "MAX_TEXTURE_BYTES", 1000)
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
