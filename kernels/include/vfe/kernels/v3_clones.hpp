// Functions built twice, for baseline x86-64 and for x86-64-v3 (AVX2), the loader picking
// the build the CPU runs (GCC's target_clones). kernels/ and engine/ compile without
// contracted multiply-adds, so both builds give the same bits. VFE_V3_CLONES_FLAT also
// inlines every callee into each build, so that they take it too. In engine/, put them on
// functions of internal linkage: the resolver of an external one is exported from
// libvfe.so. A single build under clang and under the address and thread sanitizers: the
// loader runs a resolver before the sanitizer's runtime is ready, and an instrumented one
// crashes there.
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__) && \
    !defined(__SANITIZE_THREAD__)
#define VFE_V3_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#define VFE_V3_CLONES_FLAT __attribute__((target_clones("arch=x86-64-v3", "default"), flatten))
#else
#define VFE_V3_CLONES
#define VFE_V3_CLONES_FLAT
#endif
