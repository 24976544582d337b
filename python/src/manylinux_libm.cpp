// libm's log and pow at their first x86-64 version, GLIBC_2.2.5, for the portable wheel
// (CRUSHDEM_MANYLINUX, python/CMakeLists.txt). glibc 2.29 gave both a new symbol version (the
// same functions without the SVID error handling), and a module built on a newer glibc binds to
// it: the wheel would then need glibc 2.29 for these two symbols alone. The module is linked with
// -Wl,--wrap=log,--wrap=pow, so every call of log and pow, in crushdem's library and in the
// module, comes here and goes to the GLIBC_2.2.5 symbol. Where glibc is 2.29 or later that symbol
// is a wrapper of the same implementation (identical results for every argument the engine
// passes: finite, and for log positive); on an older glibc it is that glibc's own log and pow,
// which may differ from the newer ones in the last bit (README.md, section Build).
extern "C" {
double crushdem_log_glibc_2_2_5(double x);
double crushdem_pow_glibc_2_2_5(double x, double y);
__asm__(".symver crushdem_log_glibc_2_2_5,log@GLIBC_2.2.5");
__asm__(".symver crushdem_pow_glibc_2_2_5,pow@GLIBC_2.2.5");

// NOLINTBEGIN(bugprone-reserved-identifier,cert-dcl37-c,cert-dcl51-cpp): the names ld's --wrap uses
double __wrap_log(double x) {
  return crushdem_log_glibc_2_2_5(x);
}
double __wrap_pow(double x, double y) {
  return crushdem_pow_glibc_2_2_5(x, y);
}
// NOLINTEND(bugprone-reserved-identifier,cert-dcl37-c,cert-dcl51-cpp)
}
