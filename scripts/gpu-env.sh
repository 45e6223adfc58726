# Sourced by scripts/gpu-check.sh and scripts/device-suite.sh on the lent GPU machine, in the
# repository root: the output folder ($OUT, or ./gpu-out) in `out`, the carried libraries of
# gpu-kit/ and the machine's cuFFT on the library path, and RPYFMM_EXPECT_CUDA (no usable device
# is a failure there, not a skip).
out="${OUT:-gpu-out}"
mkdir -p "$out"
cufft_dir=$(dirname "$(find /usr/local /opt /usr/lib -name 'libcufft.so.12*' 2>/dev/null | head -1)")
export LD_LIBRARY_PATH="$PWD/gpu-kit/lib:${cufft_dir}:/usr/local/cuda/lib64:${LD_LIBRARY_PATH:-}"
export RPYFMM_EXPECT_CUDA=1
