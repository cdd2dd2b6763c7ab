// Linear workgroup index over a 2D dispatch: one dimension holds at most 65535 groups, so large
// arrays are dispatched as (min(n, 65535), ceil(n / 65535)) (gpusort.py: groups()).
uint group_index() { return gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x; }
