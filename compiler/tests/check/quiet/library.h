/* A header of helpers, as shader libraries ship them: not every helper reads every parameter. */
float library_weight(float x; float unused_parameter) {
    float unused_local = 2;
    return x * 0.5;
}
