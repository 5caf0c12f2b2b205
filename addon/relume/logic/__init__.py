"""Relume's add-on logic that does not need bpy.

Everything here works on plain Python values and numpy arrays, so it can be tested and
reasoned about without Blender (Blender's glTF add-on keeps the same split). The modules in
the parent package read bpy data, call into this package, and write results back.
"""
