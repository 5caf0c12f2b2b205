"""The add-on's services: export, bake, stack loading and staleness, relit output, light
group gains, status.

Operators (`ops`), panels and the scripts' API (`api`) all call these modules, so each rule
has one home; the services call down into `exporter`, `logic` and the live image, never
back up. This package's `__init__` imports nothing: callers import the module they need.
"""
