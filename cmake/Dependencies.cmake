# Every dependency comes from a Debian 12 package through its own CMake config (imported
# targets). tools/install-deps.sh installs them all.
find_package(Threads REQUIRED)
find_package(glm CONFIG REQUIRED)
find_package(Imath CONFIG REQUIRED)
find_package(cereal CONFIG REQUIRED)
find_package(nlohmann_json CONFIG REQUIRED)
find_package(CLI11 CONFIG REQUIRED)
# The runtime: the Vulkan loader and headers, and glslc to compile shaders/ at build time.
find_package(Vulkan REQUIRED COMPONENTS glslc)

if(PROBEKIT_BUILD_TESTS)
    find_package(GTest CONFIG REQUIRED)
    find_package(benchmark CONFIG REQUIRED)
endif()

# Baker-only dependencies. They stay behind baker/'s .cpp files (never in a public header).
find_package(embree 3 CONFIG REQUIRED)
find_package(TinyGLTF CONFIG REQUIRED)
# stb_image, which libtinygltf decodes images with (Debian's libstb0, a dependency of
# libtinygltf): the glTF loader reads an image's dimensions with it before decoding. Only the
# shared library is needed (no header, so no libstb-dev): hence the versioned file name.
find_library(PROBEKIT_STB_LIBRARY NAMES stb libstb.so.0 REQUIRED)
find_package(OpenImageIO CONFIG REQUIRED)
# Debian's OpenImageIO config names /usr/include/opencv4, which no package here installs;
# drop it from the imported target so consumers do not get a missing include directory.
foreach(prop INTERFACE_INCLUDE_DIRECTORIES INTERFACE_SYSTEM_INCLUDE_DIRECTORIES)
    get_target_property(dirs OpenImageIO::OpenImageIO ${prop})
    if(dirs)
        list(FILTER dirs EXCLUDE REGEX "opencv4")
        set_target_properties(OpenImageIO::OpenImageIO PROPERTIES ${prop} "${dirs}")
    endif()
endforeach()
