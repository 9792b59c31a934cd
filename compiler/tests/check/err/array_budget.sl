// expect: E0137
// An element at a computed index is compiled as code for every element of the array.
surface wide() {
    float ramp[4000];
    float i = floor(s * 4000);
    ramp[i] = t;
    ramp[i + 1] = t;
    ramp[i + 2] = t;
    ramp[i + 3] = t;
    Ci = ramp[i] + ramp[i + 1];
}
