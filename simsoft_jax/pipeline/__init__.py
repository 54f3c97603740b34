"""The sj.run pipeline: the Result of a scene (results), the result files (output) and
Ctrl-C that is never lost (interrupts).

No imports here: importing a module of this layer loads only what that module needs.
"""
