"""Compiled code: the regressors compiled once with the system C compiler (:mod:`dynamics.codegen.compiled`)
and the on-disk cache of the design's just-in-time compiled functions (:mod:`dynamics.codegen.jit_cache`)."""
