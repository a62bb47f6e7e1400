"""Programs built on the library: the command line (:mod:`.cli`), the default scene
(:mod:`.demo`) and batch rendering on Dask (:mod:`.batch`). Nothing in the library imports them.
"""
