// expect: E0137
// Each function calls the one before twice: inlined, f13 is 2^13 copies of f0.
float f0(float x) { return x; }
float f1(float x) { return f0(x) + f0(x); }
float f2(float x) { return f1(x) + f1(x); }
float f3(float x) { return f2(x) + f2(x); }
float f4(float x) { return f3(x) + f3(x); }
float f5(float x) { return f4(x) + f4(x); }
float f6(float x) { return f5(x) + f5(x); }
float f7(float x) { return f6(x) + f6(x); }
float f8(float x) { return f7(x) + f7(x); }
float f9(float x) { return f8(x) + f8(x); }
float f10(float x) { return f9(x) + f9(x); }
float f11(float x) { return f10(x) + f10(x); }
float f12(float x) { return f11(x) + f11(x); }
float f13(float x) { return f12(x) + f12(x); }
surface exponential() {
    Ci = f13(s);
}
