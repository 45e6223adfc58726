// rpyfmm — the qualifier of functions written once for host code and CUDA kernels:
// __host__ __device__ under nvcc, nothing for the host compiler (the RPY pair tensor, the
// counter-based noise, the BD and PSE stages that run in a host loop and on the device).
#pragma once

#ifndef RPYFMM_HOST_DEVICE
#ifdef __CUDACC__
#define RPYFMM_HOST_DEVICE __host__ __device__
#else
#define RPYFMM_HOST_DEVICE
#endif
#endif
