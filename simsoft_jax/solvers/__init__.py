"""Solvers: status codes, the Newton core and the one implicit derivative
(newton), static equilibrium (statics/) and its stability count (stability),
generalized-alpha dynamics (dynamics/), vmap-friendly lanes (batched), the
compiled programs shared by sj.run, solve_static and simulate (programs),
the compiled-program cache (compile_cache) and packing.

No imports here: importing a module of this layer loads only what that module needs.
"""
