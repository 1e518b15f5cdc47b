# Installs the probekit build tree into a fresh prefix, builds examples/app against that prefix
# (not the build tree), and runs it on a synthetic volume. cmake -P with:
#   BUILD_DIR, SOURCE_DIR, WORK_DIR, PROBEKIT (the CLI, for `probekit synth`), GENERATOR
# The app exits 77 without a Vulkan device; the test then prints "SKIPPED: no Vulkan device"
# (ctest's SKIP_REGULAR_EXPRESSION).
function(run step)
    execute_process(COMMAND ${ARGN} RESULT_VARIABLE result OUTPUT_VARIABLE out ERROR_VARIABLE err)
    if(NOT result EQUAL 0)
        message(FATAL_ERROR "${step} failed (${result}):\n${out}\n${err}")
    endif()
endfunction()

file(REMOVE_RECURSE ${WORK_DIR})
set(prefix ${WORK_DIR}/prefix)
run("cmake --install" ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix})
foreach(installed include/probekit/runtime/gpu_volumes.hpp include/probekit/runtime/dynamic_gi.hpp include/probekit/shaders/probe_volume.glsl
                  include/probekit/shaders/probe_volume_layout.h share/probekit/spirv/shade.comp.spv)
    if(NOT EXISTS ${prefix}/${installed})
        message(FATAL_ERROR "the install is missing ${installed}")
    endif()
endforeach()

# Only the prefix: no package registry, no build tree.
run("configure examples/app" ${CMAKE_COMMAND} -S ${SOURCE_DIR}/examples/app -B ${WORK_DIR}/build
    -G ${GENERATOR} -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH=${prefix}
    -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF)
file(STRINGS ${WORK_DIR}/build/CMakeCache.txt found REGEX "^probekit_DIR:")
if(NOT found MATCHES "${prefix}/")
    message(FATAL_ERROR "examples/app found probekit outside the install prefix: ${found}")
endif()
run("build examples/app" ${CMAKE_COMMAND} --build ${WORK_DIR}/build)

run("probekit synth" ${PROBEKIT} synth -o ${WORK_DIR}/example.pvol --format half)
# run_example(PROGRAM IMAGE WHAT): runs the built example PROGRAM on the synthetic volume; it must
# write IMAGE (under WORK_DIR) or exit 77 (no Vulkan device). WHAT names it in the failures.
function(run_example program image what)
    execute_process(COMMAND ${WORK_DIR}/build/${program} ${WORK_DIR}/example.pvol
                            ${WORK_DIR}/${image}
                    RESULT_VARIABLE result OUTPUT_VARIABLE out ERROR_VARIABLE err)
    message(STATUS "${out}${err}")
    if(result EQUAL 77)
        message(STATUS "SKIPPED: no Vulkan device")
    elseif(NOT result EQUAL 0)
        message(FATAL_ERROR "${what} failed (${result})")
    elseif(NOT EXISTS ${WORK_DIR}/${image})
        message(FATAL_ERROR "${what} wrote no image")
    endif()
endfunction()

run_example(probekit_example_app frame.pfm "examples/app")
# The dynamic GI example, on the same volume.
run_example(probekit_example_dynamic_gi dynamic_gi.pfm "examples/app dynamic_gi")
