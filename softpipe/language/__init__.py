"""The shader language: what a shader is (:mod:`.contract`), the GLSL-like math it
calls (:mod:`.glsl`), and the generator that compiles a shader into the loop a stage runs
(:mod:`.kernels`). It sits below the pipeline, which runs shaders, and above nothing but
:mod:`softpipe.core`. Shader authors import from one module, :mod:`softpipe.shading`.
"""
