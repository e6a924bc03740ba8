// Default runtime options of the sanitizer build (PENUMBRA_SANITIZE), compiled into every
// executable that links penumbra_core. The environment (ASAN_OPTIONS, UBSAN_OPTIONS) is read
// after these and wins.
//
// detect_leaks=0: PoCL runs the kernels inside the process, on worker threads it keeps until
// exit, and LeakSanitizer's stop-the-world pass at exit races with them ("Tracer caught signal
// 11", in some processes only); PoCL and LLVM also keep allocations alive until exit on
// purpose. The code that does not touch OpenCL (file formats, scenes, the CPU reference) is
// leak-checked by scripts/test.sh in a run of its own with detect_leaks=1.
extern "C" {
const char* __asan_default_options() { return "detect_leaks=0"; }
const char* __ubsan_default_options() { return "print_stacktrace=1:halt_on_error=1"; }
}
