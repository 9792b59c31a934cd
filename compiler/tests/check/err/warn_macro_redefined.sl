// expect: W0006
// GAIN is defined a second time with a different body; the new definition
// replaces the old one, with a warning.
#define GAIN 2
#define GAIN 3

surface warn_macro_redefined()
{
    Ci = Cs * GAIN;
    Oi = Os;
}
