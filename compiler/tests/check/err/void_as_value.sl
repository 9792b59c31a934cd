// expect: E0126
// "report" returns void, so its result cannot be used as a value.
void report(float x)
{
    printf("%f\n", x);
}

surface void_as_value()
{
    float r = report(1);
    Ci = Cs * r;
    Oi = Os;
}
