"""A closed room lit only by a sun through a window: most of its light bounced more than
once, the case where what later bounces see of an edit matters."""

from __future__ import annotations

import math

import bpy

from support import cycles as cy
from support.scenes import add_camera_and_black_world


def window_room(resolution: int, walls=None, floor=None) -> None:
    """A closed 4 × 4 × 2.5 m room with a 1.6 × 1.2 m window opening in its +Y wall, a
    5 W/m² sun shining in through it at 40° elevation, black world; the camera inside,
    looking at the sunlit floor patch and the window wall. `walls` (walls and ceiling) and
    `floor` are materials; by default grey diffuse (albedo 0.7) and a warm diffuse floor."""
    walls = walls or cy.diffuse_material("Room", (0.7, 0.7, 0.7))
    floor = floor or cy.diffuse_material("RoomFloor", (0.5, 0.45, 0.4))
    w, h = 2.0, 2.5
    quads = {
        "Floor": ([(-w, -w, 0), (w, -w, 0), (w, w, 0), (-w, w, 0)], floor),
        "Ceiling": ([(-w, -w, h), (-w, w, h), (w, w, h), (w, -w, h)], walls),
        "WallS": ([(-w, -w, 0), (-w, -w, h), (w, -w, h), (w, -w, 0)], walls),
        "WallW": ([(-w, -w, 0), (-w, w, 0), (-w, w, h), (-w, -w, h)], walls),
        "WallE": ([(w, -w, 0), (w, -w, h), (w, w, h), (w, w, 0)], walls),
        # The +Y wall around a window: x ∈ [−0.8, 0.8], z ∈ [0.8, 2.0].
        "WallN_below": ([(-w, w, 0), (w, w, 0), (w, w, 0.8), (-w, w, 0.8)], walls),
        "WallN_above": ([(-w, w, 2.0), (w, w, 2.0), (w, w, h), (-w, w, h)], walls),
        "WallN_left": ([(-w, w, 0.8), (-0.8, w, 0.8), (-0.8, w, 2.0), (-w, w, 2.0)], walls),
        "WallN_right": ([(0.8, w, 0.8), (w, w, 0.8), (w, w, 2.0), (0.8, w, 2.0)], walls),
    }
    for name, (verts, mat) in quads.items():
        cy.mesh_object(name, verts, [(0, 1, 2, 3)], mat)
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 5.0
    sun.angle = math.radians(1.0)
    sun_obj = bpy.data.objects.new("Sun", sun)
    sun_obj.location = (0.0, 4.0, 4.0)
    # Local −Z → (0, −0.766, −0.643): into the room through the window, down at 40°.
    sun_obj.rotation_euler = (math.radians(-50.0), 0.0, 0.0)
    bpy.context.scene.collection.objects.link(sun_obj)
    add_camera_and_black_world(bpy.context.scene, resolution, 18, (0.3, -1.8, 1.4), (78, 0, 8))
