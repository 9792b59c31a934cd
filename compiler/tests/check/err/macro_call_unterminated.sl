// expect: E0008
// The invocation of the function-like macro SCALE on the last line is
// missing its closing parenthesis: the file ends inside the argument list.
#define SCALE(x) ((x) * 2)

surface macro_call_unterminated()
{
    Ci = Cs;
    Oi = Os;
}

SCALE(1
