// What both example programs do first: take VOLUMES.pvol OUT.pfm from the command line, read
// the volumes, and check that this machine has a Vulkan device.
#pragma once

#include <cstdio>
#include <utility>
#include <vector>

#include <probekit/formats/pvol.hpp>
#include <probekit/runtime/gpu_context.hpp>

// 0 when `file` holds the volumes and a device exists; otherwise the exit code to leave with
// (1 failure, 77 no Vulkan device: tests count that as skipped), the reason printed.
inline int startExample(int argc, char** argv, probekit::PvolFile& file) {
    if (argc != 3) {
        std::fprintf(stderr, "usage: %s VOLUMES.pvol OUT.pfm\n", argv[0]);
        return 1;
    }
    probekit::Result<probekit::PvolFile> read = probekit::readPvol(argv[1]);
    if (!read || read.value().volumes.empty()) {
        std::fprintf(stderr, "%s\n", read ? "no volumes" : read.error().message.c_str());
        return 1;
    }
    file = std::move(read.value());
    probekit::Result<std::vector<probekit::runtime::DeviceInfo>> devices =
        probekit::runtime::enumerateDevices();
    if (!devices || devices.value().empty()) {
        std::printf("no Vulkan device: nothing to render\n");
        return 77;
    }
    return 0;
}
