// expect: E0005
// Malformed directive: #define must be followed by a macro name.
#define

surface define_no_name()
{
    Ci = Cs;
    Oi = Os;
}
