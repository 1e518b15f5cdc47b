# Every dependency comes from a Debian 12 package through its own CMake config (imported
# targets). tools/install-deps.sh installs them all.
find_package(Threads REQUIRED)
find_package(glm CONFIG REQUIRED)
find_package(Imath CONFIG REQUIRED)
find_package(cereal CONFIG REQUIRED)
find_package(nlohmann_json CONFIG REQUIRED)
find_package(CLI11 CONFIG REQUIRED)

if(PROBEKIT_BUILD_TESTS)
    find_package(GTest CONFIG REQUIRED)
    find_package(benchmark CONFIG REQUIRED)
endif()
