// The glTF loader's file access and memory account: the folder rule (AssetFolder), reads that
// cannot block (readRegularFile), and the tinygltf callbacks that route every buffer and image
// read through both (gltf_input.hpp says why tinygltf's own callbacks are not used).
#include <cerrno>
#include <cstring>
#include <string_view>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <tiny_gltf.h>

#include "probekit/baker/folder_rule.hpp"
#include "scene/gltf_input.hpp"

// stb_image decodes the images (tinygltf's default loader calls it). Its header comes with
// Debian's libstb-dev, which nothing else needs; the library is libstb0, which libtinygltf
// already depends on. These two declarations are stb_image.h's.
extern "C" {
int stbi_info_from_memory(const unsigned char* buffer, int len, int* x, int* y, int* comp);
int stbi_is_16_bit_from_memory(const unsigned char* buffer, int len);
}

namespace probekit::baker::gltf {

namespace fs = std::filesystem;

std::string MemoryBudget::refusal(const std::string& what, uint64_t bytes) const {
    return what + " needs " + std::to_string(bytes) + " bytes; with " + std::to_string(m_used) +
           " bytes already loaded that exceeds the memory limit of " + std::to_string(m_limit) +
           " bytes (LoadOptions::maxMemoryBytes; probekit bake: max_memory_mb)";
}

namespace {

// The canonical form of an existing folder, or empty.
fs::path canonicalFolder(const fs::path& folder) {
    std::error_code ec;
    const fs::path absolute = fs::absolute(folder, ec);
    if (ec) {
        return {};
    }
    fs::path canonical = fs::canonical(absolute, ec);
    if (ec || !fs::is_directory(canonical, ec)) {
        return {};
    }
    return canonical;
}

// Component by component, so /data/scene-old is not under /data/scene.
bool isUnder(const fs::path& path, const fs::path& root) {
    auto p = path.begin();
    for (auto r = root.begin(); r != root.end(); ++r, ++p) {
        if (r->empty()) {
            continue; // a trailing separator
        }
        if (p == path.end() || *p != *r) {
            return false;
        }
    }
    return true;
}

bool underAny(const fs::path& path, const std::vector<fs::path>& roots) {
    return std::any_of(roots.begin(), roots.end(),
                       [&](const fs::path& root) { return isUnder(path, root); });
}

// Whether absolute `candidate` stays under one of the canonical `roots`: first by where its
// components lead (decided before whether it exists, so a refusal says nothing about files
// outside), then, when it exists, by its canonical path (a link inside that points out).
// `real` receives the canonical path, empty when the file is missing.
bool leadsUnder(const fs::path& candidate, const std::vector<fs::path>& roots, fs::path& real) {
    std::error_code ec;
    fs::path leads_to = fs::weakly_canonical(candidate, ec);
    if (ec) {
        leads_to = candidate.lexically_normal();
    }
    if (!underAny(leads_to, roots)) {
        return false;
    }
    real = fs::canonical(candidate, ec);
    if (ec) {
        real.clear();
        return true;
    }
    return underAny(real, roots);
}

const char* fileKind(mode_t mode) {
    if (S_ISDIR(mode)) {
        return "a directory";
    }
    if (S_ISFIFO(mode)) {
        return "a FIFO";
    }
    if (S_ISCHR(mode) || S_ISBLK(mode)) {
        return "a device";
    }
    if (S_ISSOCK(mode)) {
        return "a socket";
    }
    return "not a regular file";
}

} // namespace

AssetFolder::AssetFolder(const fs::path& scene_name, const std::vector<fs::path>& extra_roots) {
    std::error_code ec;
    const fs::path absolute = fs::absolute(scene_name, ec);
    const fs::path base = ec ? fs::path() : canonicalFolder(absolute.parent_path());
    if (!base.empty()) {
        m_base = base.string();
        m_roots.push_back(base);
    }
    for (const fs::path& root : extra_roots) {
        if (fs::path canonical = canonicalFolder(root); !canonical.empty()) {
            m_roots.push_back(std::move(canonical));
        } else {
            m_unresolved.push_back(root.string());
        }
    }
}

AssetFolder::Resolved AssetFolder::resolve(const std::string& decoded) const {
    using Kind = Resolved::Kind;
    const std::string outside =
        "resolves outside the scene's folder " + m_base +
        "; probekit reads only regular files under it and under the folders of "
        "LoadOptions::assetRoots (--asset-root)";
    if (decoded.find('\0') != std::string::npos) {
        return {Kind::Refused, {}, "holds a NUL byte"};
    }
    const bool drive =
        decoded.size() >= 2 && decoded[1] == ':' &&
        ((decoded[0] >= 'A' && decoded[0] <= 'Z') || (decoded[0] >= 'a' && decoded[0] <= 'z'));
    if (!decoded.empty() && (decoded[0] == '/' || decoded[0] == '\\' || drive)) {
        return {Kind::Refused,
                {},
                "is an absolute path; probekit reads only paths relative to "
                "the scene's folder"};
    }
    if (decoded.empty() || m_base.empty()) {
        return {Kind::Missing, {}, {}};
    }
    fs::path real;
    if (!leadsUnder(fs::path(m_base) / decoded, m_roots, real)) {
        return {Kind::Refused, {}, outside};
    }
    if (real.empty()) {
        return {Kind::Missing, {}, {}};
    }
    struct stat info;
    if (::stat(real.c_str(), &info) != 0) {
        return {Kind::Missing, {}, {}};
    }
    if (!S_ISREG(info.st_mode)) {
        return {Kind::Refused,
                {},
                std::string("names ") + fileKind(info.st_mode) + ", not a regular file"};
    }
    return {Kind::File, real, {}};
}

Result<std::vector<uint8_t>> readRegularFile(const fs::path& path, const std::string& label,
                                             MemoryBudget& budget) {
    // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer.
    const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) {
        return Error{ErrorCode::Io, label + ": cannot open: " + std::strerror(errno)};
    }
    struct Closer {
        int fd;
        ~Closer() { ::close(fd); }
    } closer{fd};
    struct stat info;
    if (::fstat(fd, &info) != 0) {
        return Error{ErrorCode::Io, label + ": cannot stat: " + std::strerror(errno)};
    }
    if (!S_ISREG(info.st_mode)) {
        return Error{ErrorCode::Io,
                     label + " is " + fileKind(info.st_mode) + ", not a regular file"};
    }
    const uint64_t size = static_cast<uint64_t>(info.st_size);
    if (!budget.fits(size)) {
        return Error{ErrorCode::OutOfRange, budget.refusal(label, size)};
    }
    std::vector<uint8_t> bytes(size);
    size_t done = 0;
    while (done < bytes.size()) {
        const ssize_t n = ::read(fd, bytes.data() + done, bytes.size() - done);
        if (n < 0 && errno == EINTR) {
            continue;
        }
        if (n < 0) {
            return Error{ErrorCode::Io, label + ": read failed: " + std::strerror(errno)};
        }
        if (n == 0) {
            break; // the file shrank since fstat
        }
        done += static_cast<size_t>(n);
    }
    bytes.resize(done);
    budget.add(size);
    return bytes;
}

namespace {

IoContext& contextOf(void* user) {
    return *static_cast<IoContext*>(user);
}

void refuse(IoContext& context, ErrorCode code, const std::string& what, std::string* err) {
    if (!context.refusal) {
        context.refusal = LoadError{code, context.file + ": " + what};
    }
    if (err) {
        *err += what + "\n";
    }
}

// The URI tinygltf joined to base_dir, or nothing for its second search path, the working
// directory (which probekit never reads).
std::optional<std::string> uriOf(const IoContext& context, const std::string& joined) {
    const std::string& base = context.folder.base();
    if (base.empty()) {
        return std::nullopt;
    }
    const std::string prefix = base.back() == '/' ? base : base + '/';
    if (!std::string_view(joined).starts_with(prefix)) {
        return std::nullopt;
    }
    // tinygltf took '+' for a space; the document's URI said which file it names.
    const std::string decoded = joined.substr(prefix.size());
    const auto named = context.uriPaths.find(decoded);
    return named != context.uriPaths.end() ? named->second : decoded;
}

bool fileExists(const std::string& joined, void* user) {
    IoContext& context = contextOf(user);
    const std::optional<std::string> uri = uriOf(context, joined);
    if (!uri) {
        return false;
    }
    const AssetFolder::Resolved resolved = context.folder.resolve(*uri);
    if (resolved.kind == AssetFolder::Resolved::Refused) {
        refuse(context, ErrorCode::InvalidArgument, "URI '" + *uri + "' " + resolved.reason,
               nullptr);
    }
    return resolved.kind == AssetFolder::Resolved::File;
}

// No ~ or $VARIABLE expansion: a URI is a path relative to the scene's folder, nothing more.
std::string expandFilePath(const std::string& path, void*) {
    return path;
}

bool readWholeFile(std::vector<unsigned char>* out, std::string* err, const std::string& joined,
                   void* user) {
    IoContext& context = contextOf(user);
    const std::optional<std::string> uri = uriOf(context, joined);
    if (!uri) {
        if (err) {
            *err += "not under the scene's folder\n";
        }
        return false;
    }
    const AssetFolder::Resolved resolved = context.folder.resolve(*uri);
    if (resolved.kind != AssetFolder::Resolved::File) {
        refuse(context, ErrorCode::InvalidArgument,
               "URI '" + *uri + "' " +
                   (resolved.reason.empty() ? std::string("names no file") : resolved.reason),
               err);
        return false;
    }
    Result<std::vector<uint8_t>> bytes =
        readRegularFile(resolved.path, "URI '" + *uri + "'", context.budget);
    if (!bytes) {
        refuse(context, bytes.error().code, bytes.error().message, err);
        return false;
    }
    *out = std::move(bytes).value();
    context.read.push_back(resolved.path);
    return true;
}

bool writeWholeFile(std::string* err, const std::string&, const std::vector<unsigned char>&,
                    void*) {
    if (err) {
        *err += "the loader never writes files\n";
    }
    return false;
}

// tinygltf's image loader behind two checks on the header alone: the pixel limit and the
// budget, for stb's decoded buffer, tinygltf's copy of it and the baker's float texels.
bool loadImage(tinygltf::Image* image, const int index, std::string* err, std::string* warn,
               int required_width, int required_height, const unsigned char* bytes, int size,
               void* user) {
    IoContext& context = contextOf(user);
    const size_t i = size_t(index);
    if (i < context.images.extensionOnly.size() && context.images.extensionOnly[i]) {
        return true; // a WebP/KTX2/DDS source beside a fallback: no material reads it
    }
    const std::string field =
        "images[" + std::to_string(index) + "]" +
        (i < context.images.names.size() ? " " + context.images.names[i] : std::string());
    int width = 0;
    int height = 0;
    int channels = 0;
    if (bytes == nullptr || size <= 0 ||
        stbi_info_from_memory(bytes, size, &width, &height, &channels) == 0 || width <= 0 ||
        height <= 0) {
        refuse(context, ErrorCode::InvalidArgument,
               field + " is not an image the decoder reads (PNG or JPEG)", err);
        return false;
    }
    const uint64_t pixels = uint64_t(width) * uint64_t(height);
    const std::string dimensions = std::to_string(width) + " x " + std::to_string(height);
    if (pixels > kMaxImagePixels) {
        refuse(context, ErrorCode::OutOfRange,
               field + " is " + dimensions + " pixels, more than the limit of " +
                   std::to_string(kMaxImagePixels) + " (8192 x 8192)",
               err);
        return false;
    }
    const uint64_t channel_bytes = stbi_is_16_bit_from_memory(bytes, size) != 0 ? 2 : 1;
    const uint64_t needed = pixels * (2 * 4 * channel_bytes + sizeof(float) * 4);
    if (!context.budget.fits(needed)) {
        refuse(context, ErrorCode::OutOfRange,
               context.budget.refusal(field + " (" + dimensions + " pixels, decoded)", needed),
               err);
        return false;
    }
    context.budget.add(needed);
    // Null user data: tinygltf's default options, RGBA at the file's bit depth.
    return tinygltf::LoadImageData(image, index, err, warn, required_width, required_height, bytes,
                                   size, nullptr);
}

} // namespace

void installIoCallbacks(tinygltf::TinyGLTF& parser, IoContext& context) {
    parser.SetFsCallbacks(tinygltf::FsCallbacks{&fileExists, &expandFilePath, &readWholeFile,
                                                &writeWholeFile, &context});
    parser.SetImageLoader(&loadImage, &context);
}

} // namespace probekit::baker::gltf

namespace probekit::baker {

std::optional<std::filesystem::path>
pathUnderRoots(const std::filesystem::path& named,
               const std::vector<std::filesystem::path>& roots) {
    namespace fs = std::filesystem;
    std::vector<fs::path> canonical_roots;
    for (const fs::path& root : roots) {
        if (fs::path canonical = gltf::canonicalFolder(root); !canonical.empty()) {
            canonical_roots.push_back(std::move(canonical));
        }
    }
    std::error_code ec;
    const fs::path absolute = fs::absolute(named, ec);
    fs::path real;
    if (ec || named.empty() || !gltf::leadsUnder(absolute, canonical_roots, real)) {
        return std::nullopt;
    }
    return real.empty() ? absolute.lexically_normal() : real;
}

} // namespace probekit::baker
