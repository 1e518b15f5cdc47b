# Fails when any C++ source under the project's own folders differs from clang-format's output.
file(GLOB_RECURSE sources
    ${SOURCE_DIR}/formats/*.cpp ${SOURCE_DIR}/formats/*.hpp
    ${SOURCE_DIR}/baker/*.cpp ${SOURCE_DIR}/baker/*.hpp
    ${SOURCE_DIR}/runtime/*.cpp ${SOURCE_DIR}/runtime/*.hpp
    ${SOURCE_DIR}/viewer/*.cpp ${SOURCE_DIR}/viewer/*.hpp
    ${SOURCE_DIR}/tools/*.cpp ${SOURCE_DIR}/tools/*.hpp
    ${SOURCE_DIR}/tests/*.cpp ${SOURCE_DIR}/tests/*.hpp
    ${SOURCE_DIR}/examples/*.cpp)
execute_process(COMMAND ${CLANG_FORMAT} --dry-run --Werror ${sources}
                RESULT_VARIABLE result ERROR_VARIABLE errors)
if(NOT result EQUAL 0)
    message(FATAL_ERROR "clang-format: files differ from .clang-format (run tools/format.sh):\n${errors}")
endif()
