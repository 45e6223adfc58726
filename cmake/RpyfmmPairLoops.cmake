# rpyfmm_vectorize_pair_loops(<source>...): compile options for sources whose hot pair loops
# evaluate every regime branch-free and select (r = 0 skips, near/far RPY regimes).
#  - -fno-math-errno: sqrt sets no errno, so it is an instruction, not a libm call;
#  - -fno-trapping-math: GCC may evaluate both sides of a select (1/r where r = 0 is discarded).
#    Without it GCC if-converts such loops only where AVX-512 masking hides the speculation, so
#    the AVX2 and baseline clones would run scalar (measured on an AVX2-only CPU: the FmmRpy near
#    field 1.75x and the Laplace P2P 4x slower).
# Neither flag changes a formula or allows reassociation; results differ only by rounding where a
# reduction runs in vector lanes (as it does in the AVX-512 clones). The kernels never
# read errno or FP exception flags.
function(rpyfmm_vectorize_pair_loops)
  set_source_files_properties(${ARGN} PROPERTIES COMPILE_OPTIONS
    "$<$<CXX_COMPILER_ID:GNU,Clang>:-fno-math-errno;-fno-trapping-math>")
endfunction()
