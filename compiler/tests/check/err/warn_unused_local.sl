// expect: W0001
// The local variable "unused" is declared and initialised but never read.
surface warn_unused_local()
{
    float unused = 1;
    Ci = Cs;
    Oi = Os;
}
