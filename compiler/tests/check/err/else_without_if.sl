// expect: E0004
// An #else with no conditional directive open before it.
#define DEBUG 1
#else
surface else_without_if()
{
    Ci = Cs;
    Oi = Os;
}
