"""The exporter: Blender's evaluated scene → a Relume scene (docs/design.md §3).

bpy is read here and only here; the mapping rules live in `..logic` (bpy-free).
"""
