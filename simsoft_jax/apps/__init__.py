"""Applications: the Princeton beam experiment and its figures, and the
cosseratbench solver adapter.

No imports here: importing a module of this layer loads only what that module needs.
"""
