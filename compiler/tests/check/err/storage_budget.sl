// expect: E0138
// Each call of `blur` is compiled as a copy with its own `taps`: four copies of 1200 floats.
float blur(float x) {
    float taps[1200];
    taps[0] = x;
    return taps[0];
}
surface fourcopies() {
    Ci = blur(s) + blur(t) + blur(u) + blur(v);
}
