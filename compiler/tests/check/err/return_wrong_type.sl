// expect: E0116
// "label" is declared to return a float but returns a string.
float label(color c)
{
    return "red";
}

surface return_wrong_type()
{
    Ci = Cs * label(Cs);
    Oi = Os;
}
