"""The sj.run pipeline: the Result of a scene (results) and the result files (output).

No imports here: importing a module of this layer loads only what that module needs.
"""
