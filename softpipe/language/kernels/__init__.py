"""How shaders run: the generated loops that inline them, numba's compilation and cache, errors.

For each (shader, varying layout) softpipe writes a small Python module, a loop
over the batch with the shader inlined, and compiles it with numba; under
``NUMBA_DISABLE_JIT=1`` the same loop runs as Python. One concern per module,
bottom to top:

- :mod:`.snapshot`: what a shader is compiled with (the globals it reads are part
  of a loop's key; its plain Python helpers are compiled with it).
- :mod:`.template`, ``templates/``: the fixed parts of the loops, as Python files a
  linter reads; :mod:`.template` takes a function out of one and fills it in.
- :mod:`.cache`: where generated modules are kept, in memory and on disk.
- :mod:`.generate`: the code generator (vertex loop, fragment loops, the fast
  path's visible loops).
- :mod:`.diagnostics`: numba's errors and a shader's exceptions as a ShaderError
  naming the user's line; the check of a returned color (``rgba``).
- :mod:`.analysis`: what a shader's code says before it runs (``may_discard``,
  ``may_raise``, ``alpha_is_finite``) and the probes.

Arrays reach the loops *borrowed* (:mod:`softpipe.core.borrow`). This package
re-exports the names the pipeline calls, and those the generated modules import
(``borrowed_tuple``, ``jit_function``, ``rgba``, ``short_repr``, and ``outputs`` for a
framebuffer of several attachments). More:
docs/shaders.md (writing shaders), docs/05-fragment.md (a generated loop),
docs/08-fast-path.md (the fast path's questions and loops).
"""
from softpipe.core.borrow import borrowed_tuple
from softpipe.language.kernels.analysis import alpha_is_finite, may_discard, may_raise, probe_vertex_shader
from softpipe.language.kernels.diagnostics import (
                                                finite_rgba,
                                                fragment_site,
                                                outputs,
                                                rgba,
                                                run_compiled,
                                                vertex_site,
                                                visible_site,
)
from softpipe.language.kernels.generate import (
                                                fragment_kernel,
                                                fragment_module,
                                                jit_function,
                                                kernel_source,
                                                primitive_kernel,
                                                python_fragment_module,
                                                short_repr,
                                                vertex_kernel,
                                                visible_kernel,
)

__all__ = ["vertex_kernel", "fragment_module", "fragment_kernel", "visible_kernel", "primitive_kernel",
           "python_fragment_module", "kernel_source", "run_compiled", "vertex_site", "fragment_site", "visible_site",
           "may_discard", "may_raise", "alpha_is_finite", "probe_vertex_shader", "borrowed_tuple", "jit_function", "rgba", "finite_rgba",
           "short_repr", "outputs"]
