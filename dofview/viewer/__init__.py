"""The interactive viewer (``dofview view``): a glfw window with an ImGui panel on the one renderer.

Modules: app (the sub-command), window (glfw + GL + ImGui), viewer (state and frame loop),
controls (camera maths), settings (panel values → Lens/Tonemap/RenderSettings, focus pull),
sorter (depth sort off the UI thread), loader (scene loading off the UI thread), input (mouse and
keys), panel (the ImGui layer), script (the scripted mode used by tests).
"""
