"""The attachment formats a framebuffer takes are public (``sp.ATTACHMENT_FORMATS``, issue #31's leftover): a user
reads them instead of guessing, and the error for a format that is not one lists them from that one tuple."""
from __future__ import annotations

import pytest

import softpipe as sp


def test_the_attachment_formats_are_exported_and_each_makes_an_attachment():
    assert sp.ATTACHMENT_FORMATS == ("rgba8", "rgba32f", "r32f", "r32i")
    assert "ATTACHMENT_FORMATS" in sp.__all__
    for fmt in sp.ATTACHMENT_FORMATS:
        fb = sp.Framebuffer(2, 2, attachments={"color": "rgba8", "extra": fmt})
        assert fb.attachments == {"color": "rgba8", "extra": fmt}


@pytest.mark.parametrize("fmt", ["rgb32f", "RGBA8", ["rgba8"], 8])
def test_an_unknown_format_is_named_and_the_formats_listed_from_the_export(fmt):
    with pytest.raises(ValueError) as e:
        sp.Framebuffer(2, 2, attachments={"color": "rgba8", "n": fmt})
    assert str(e.value) == f"Framebuffer attachment 'n': format must be one of {sp.ATTACHMENT_FORMATS}, got {fmt!r}"
    assert str(e.value).endswith(f"one of ('rgba8', 'rgba32f', 'r32f', 'r32i'), got {fmt!r}")
