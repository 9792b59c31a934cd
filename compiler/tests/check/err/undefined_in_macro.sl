// expect: E0100
// The macro's body names a variable that does not exist; the error points
// at the macro call and a note says which macro it is and where it is defined.
#define SHADE(c) Ci = c * undefined_tint
surface undefined_in_macro()
{
    SHADE(Cs);
    Oi = Os;
}
