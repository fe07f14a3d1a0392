// A fault of the machine's OpenCL after a good start, for the kernels.launch_fault.* tests: loaded
// with LD_PRELOAD ahead of the OpenCL loader, it fails clEnqueueNDRangeKernel with
// CL_OUT_OF_RESOURCES for the kernel that GROTTO_TEST_FAIL_KERNEL names, and passes every other
// call to the loader.
#include <dlfcn.h>

#include <CL/cl.h>

#include <cstdlib>
#include <cstring>

extern "C" cl_int clEnqueueNDRangeKernel(cl_command_queue queue, cl_kernel kernel, cl_uint dims,
                                         const size_t* offset, const size_t* global,
                                         const size_t* local, cl_uint waits, const cl_event* wait,
                                         cl_event* event) {
  using Fn = cl_int (*)(cl_command_queue, cl_kernel, cl_uint, const size_t*, const size_t*,
                        const size_t*, cl_uint, const cl_event*, cl_event*);
  static const Fn next = reinterpret_cast<Fn>(dlsym(RTLD_NEXT, "clEnqueueNDRangeKernel"));
  if (const char* failing = std::getenv("GROTTO_TEST_FAIL_KERNEL")) {
    char name[128] = {};
    if (clGetKernelInfo(kernel, CL_KERNEL_FUNCTION_NAME, sizeof name - 1, name, nullptr) ==
            CL_SUCCESS &&
        std::strcmp(name, failing) == 0) {
      return CL_OUT_OF_RESOURCES;
    }
  }
  if (next == nullptr) return CL_INVALID_OPERATION;
  return next(queue, kernel, dims, offset, global, local, waits, wait, event);
}
