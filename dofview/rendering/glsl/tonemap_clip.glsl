// clip (Eq. 7): twin of tonemap/clip.py
vec3 tone_map(vec3 lin) {
    return clamp(lin, 0.0, 1.0);
}
