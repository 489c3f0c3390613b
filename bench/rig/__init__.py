"""Rig files: devices by role, each bench's own tables, bring-up of any rig."""
