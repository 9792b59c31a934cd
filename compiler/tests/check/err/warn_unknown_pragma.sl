// expect: W0005
// "#pragma nonsense" is not a pragma the compiler knows; it is ignored
// with a warning.
#pragma nonsense

surface warn_unknown_pragma()
{
    Ci = Cs;
    Oi = Os;
}
