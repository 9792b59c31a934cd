// expect: E0132
// The function "gain" is defined twice with the same signature.
float gain(float x) { return x * 2; }
float gain(float x) { return x * 3; }

surface function_defined_twice()
{
    Ci = Cs * gain(.5);
    Oi = Os;
}
