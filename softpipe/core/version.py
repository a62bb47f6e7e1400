"""softpipe's version, in one place: ``softpipe.__version__``, ``softpipe --version``, and the batch
manifest's content key (a frame rendered by another version is rendered again) read it here."""

__all__ = ["VERSION"]

#: Kept equal to pyproject.toml's ``version`` (tests/test_architecture.py checks it).
VERSION = "0.1.0"
