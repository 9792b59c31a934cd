// expect: E0134
// A shader parameter named like a shader global would hide it: here the
// parameter "Cs" would make the surface colour unreachable.
surface param_named_like_global(color Cs = 1;)
{
    Ci = Cs;
    Oi = Os;
}
