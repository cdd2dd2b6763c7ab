"""The interactive viewer (``dofview view``): a glfw window with an ImGui panel on the one renderer.

Modules: app (the sub-command); the model without a window, in layers: views (scene, renderer,
rig, views, loading, a LOD set's streaming), focusing (focus, pulls, the lens a view opens with),
model (the frames: previews while moving, the full frame, refinement; saving); beside it
interaction (the frame-time budget and its previews), streaming (a LOD set's chunks gathered off
the UI thread), adaptation (tone-mapping statistics), loader (scene loading off the UI thread),
settings (panel values → Lens/Tonemap/RenderSettings, focus pull), controls (camera maths); the
window: viewer (the model in a window: the frame loop), window (glfw + GL + ImGui), input (mouse
and keys), panel (the ImGui layer), script (the scripted mode used by tests). The depth sort off
the UI thread is the quad backend's own (rendering/sort_thread.py).
"""
