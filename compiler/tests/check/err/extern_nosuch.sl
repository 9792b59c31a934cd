// expect: E0123
// The nested function declares "extern float nosuch", but no enclosing
// scope has a variable of that name.
surface extern_nosuch(float Kd = 1;)
{
    float scaled()
    {
        extern uniform float Kd;
        extern float nosuch;
        return Kd * nosuch;
    }
    Ci = Cs * scaled();
    Oi = Os;
}
