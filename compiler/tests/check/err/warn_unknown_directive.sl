// expect: W0005
// "#foo" is not a preprocessor directive; it is ignored with a warning.
#foo

surface warn_unknown_directive()
{
    Ci = Cs;
    Oi = Os;
}
