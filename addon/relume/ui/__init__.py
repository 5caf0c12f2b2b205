"""The add-on's user interface: operators, panels, preferences and the properties they
draw. These modules use bpy and call `services/` for the work; no other part imports them,
except for the preferences (`ui.prefs.get_prefs`)."""
