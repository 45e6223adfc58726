// rpyfmm::bd::device — the qualifier of the BD stages that run both in a host loop and in a CUDA
// kernel (docs/gpu-bd.md): __host__ __device__ under nvcc, nothing for the host compiler. The
// same guard as rpyfmm/rpy/random.hpp and rpy_kernel.hpp, so that the headers mix.
#pragma once

#ifndef RPYFMM_HOST_DEVICE
#ifdef __CUDACC__
#define RPYFMM_HOST_DEVICE __host__ __device__
#else
#define RPYFMM_HOST_DEVICE
#endif
#endif
