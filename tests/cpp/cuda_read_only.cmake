# tests/cpp/cuda_read_only.cmake — nvcc compiles one kernel (cuda_read_only.cu)
# to PTX; the test fails unless the model's reads are read-only loads.
#   cmake -DNVCC=... -DSRC=<project> -DOUT=<file.ptx> -P cuda_read_only.cmake
# Inverse dynamics reads each body's joint, placement and inertia: about 120
# loads through the read-only cache, against about 10 (other constant fields)
# when the bodies arrive as a plain struct member, as they did before.
execute_process(
  COMMAND ${NVCC} -std=c++17 -O3 -arch=compute_90 --ptx -DNDEBUG -I${SRC}/include -I${SRC}/src/cuda
          ${SRC}/tests/cpp/cuda_read_only.cu -o ${OUT}
  RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "nvcc failed on cuda_read_only.cu:\n${err}")
endif()
file(STRINGS ${OUT} nc REGEX "ld\\.global\\.nc")
file(STRINGS ${OUT} all REGEX "ld\\.global")
list(LENGTH nc n_nc)
list(LENGTH all n_all)
message(STATUS "inverse dynamics kernel: ${n_nc} of ${n_all} global loads through the read-only cache")
if(n_nc LESS 60)
  message(FATAL_ERROR "the model's bodies are not read through the read-only cache (ld.global.nc: ${n_nc}, "
                      "expected at least 60): op_kernel's bodies must stay a const __restrict__ parameter")
endif()
