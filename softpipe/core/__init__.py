"""Foundations that every other folder may use and that import nothing of softpipe's above core:
the thread bands (:mod:`.parallel`), process settings and memory checks (:mod:`.runtime`),
confined, atomic file access (:mod:`.files`), color names (:mod:`.colors`), the checking of
values someone wrote, in a file or to the Python API (:mod:`.validation`), arrays handed
to compiled code without their owner (:mod:`.borrow`), and streaming stores for buffers written
once and read by someone else (:mod:`.streaming`).
"""
