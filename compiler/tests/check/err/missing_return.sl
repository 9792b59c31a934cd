// expect: E0119
// "ramp" returns a float, but when x <= 0 control reaches the end of the
// function without a return statement.
float ramp(float x)
{
    if (x > 0)
        return min(x, 1);
}

surface missing_return()
{
    Ci = Cs * ramp(s);
    Oi = Os;
}
