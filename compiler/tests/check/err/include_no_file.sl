// expect: E0005
// Malformed directive: #include names no file (neither "file" nor <file>).
#include

surface include_no_file()
{
    Ci = Cs;
    Oi = Os;
}
