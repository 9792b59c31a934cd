// expect: E0130
surface huge() {
    float a[2000000];
    Ci = a[0];
}
