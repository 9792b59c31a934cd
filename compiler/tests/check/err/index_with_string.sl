// expect: E0117
// Array indices must be floats; a string index is not allowed.
surface index_with_string()
{
    float weights[3] = {.2, .3, .5};
    Ci = Cs * weights["red"];
    Oi = Os;
}
