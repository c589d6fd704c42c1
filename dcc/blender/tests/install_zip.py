"""Runs inside Blender: installs the extension zip as an artist would (Install from Disk)
and prints whether the Tessera engine registered."""

import sys

import bpy

result = bpy.ops.extensions.package_install_files(filepath=sys.argv[-1], repo="user_default", enable_on_install=True)
engines = [getattr(e, "bl_idname", None) for e in bpy.types.RenderEngine.__subclasses__()]
print("installed:", sorted(result), "engine:", "TESSERA" in engines)
