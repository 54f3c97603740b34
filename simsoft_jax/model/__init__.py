"""Scene -> Model: the Model pytree and its optional parts (parts), the tables
built from a scene (loads and their time laws, fields, actuators, joints), and
the built-model cache.

No imports here: importing a module of this layer loads only what that module needs.
"""
