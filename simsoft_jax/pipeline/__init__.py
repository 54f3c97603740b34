"""The sj.run pipeline: the Result of a scene, the compiled programs it shares with
solve_static and simulate (programs), and the result files.

No imports here: importing a module of this layer loads only what that module needs.
"""
