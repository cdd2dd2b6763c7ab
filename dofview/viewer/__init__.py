"""The interactive viewer (``dofview view``): a glfw window with an ImGui panel on the one renderer.

Modules: app (the sub-command); model (the state and its actions, without a window: scene, rig,
focus, sort, refinement, adaptation, saving); viewer (the model in a window: the frame loop);
window (glfw + GL + ImGui); controls (camera maths); settings (panel values → Lens/Tonemap/
RenderSettings, focus pull); loader (scene loading off the UI thread); input (mouse and keys);
panel (the ImGui layer); script (the scripted mode used by tests). The depth sort off the UI thread
is the quad backend's own (rendering/sort_thread.py).
"""
