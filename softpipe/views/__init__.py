"""The debugger's pictures of a draw: every stage as an image (:mod:`.pictures`) and
the self-contained explorer page of a trace (:mod:`.explorer`).
"""
