"""Foundations that every other folder may use and that import nothing of softpipe's:
the thread bands (:mod:`.parallel`), process settings and memory checks (:mod:`.runtime`),
confined, atomic file access (:mod:`.files`), color names (:mod:`.colors`), arrays handed
to compiled code without their owner (:mod:`.borrow`).
"""
