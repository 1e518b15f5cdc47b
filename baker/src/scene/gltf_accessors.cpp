// glTF accessors -> float or index arrays: every byte range checked against its bufferView and
// buffer, components decoded per the glTF 2.0 rules, sparse values substituted. Part of
// GltfLoader (gltf_loader.hpp).
#include <algorithm>
#include <cstring>
#include <type_traits>

#include "scene/gltf_loader.hpp"

namespace probekit::baker::gltf {

namespace {

// Largest accessor without a bufferView (all zeros until sparse values apply) that we allocate;
// 2^24 elements is far beyond any real sparse accessor.
constexpr size_t kMaxUnbackedElements = size_t(1) << 24;

const char* typeName(int type) {
    switch (type) {
    case TINYGLTF_TYPE_SCALAR:
        return "SCALAR";
    case TINYGLTF_TYPE_VEC2:
        return "VEC2";
    case TINYGLTF_TYPE_VEC3:
        return "VEC3";
    case TINYGLTF_TYPE_VEC4:
        return "VEC4";
    default:
        return "a matrix type";
    }
}

// The value of type T stored at p, read through memcpy (little-endian, any alignment).
template <class T>
T loadAs(const uint8_t* p) {
    T v;
    std::memcpy(&v, p, sizeof(v));
    return v;
}

// One component as a double (exact for every integer type). Normalized integers follow the
// glTF 2.0 dequantisation rules (signed: max(c / (2^(n-1) - 1), -1)). Values are read
// little-endian through memcpy, which is also what makes unaligned offsets legal.
double readComponent(const uint8_t* p, int component_type, bool normalized) {
    switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
        return normalized ? std::max(loadAs<int8_t>(p) / 127.0, -1.0) : loadAs<int8_t>(p);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
        return normalized ? loadAs<uint8_t>(p) / 255.0 : loadAs<uint8_t>(p);
    case TINYGLTF_COMPONENT_TYPE_SHORT:
        return normalized ? std::max(loadAs<int16_t>(p) / 32767.0, -1.0) : loadAs<int16_t>(p);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
        return normalized ? loadAs<uint16_t>(p) / 65535.0 : loadAs<uint16_t>(p);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
        return normalized ? loadAs<uint32_t>(p) / 4294967295.0 : loadAs<uint32_t>(p);
    default:
        return loadAs<float>(p);
    }
}

} // namespace

size_t componentSize(int component_type) {
    switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
        return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
        return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
        return 4;
    default:
        return 0; // INT and DOUBLE are not glTF 2.0 accessor component types
    }
}

size_t componentCount(int type) {
    switch (type) {
    case TINYGLTF_TYPE_SCALAR:
        return 1;
    case TINYGLTF_TYPE_VEC2:
        return 2;
    case TINYGLTF_TYPE_VEC3:
        return 3;
    case TINYGLTF_TYPE_VEC4:
        return 4;
    default:
        return 0; // matrices are never vertex or index data here
    }
}

// Reads accessor `index` as `count x components` values of type T (float, or uint32_t for
// indices), with every byte range checked against its bufferView and buffer, and sparse
// substitution applied. `usage` names the accessor's role in messages.
template <class T>
std::vector<T> GltfLoader::readAccessor(int index, int expected_type, bool indices,
                                        const std::string& usage) const {
    const std::string field =
        "accessors[" + std::to_string(index) + "]" + (usage.empty() ? "" : " (" + usage + ")");
    const tinygltf::Accessor& accessor = checkedAccessor(index, expected_type, indices, field);
    const size_t component_size = componentSize(accessor.componentType);
    const size_t components = componentCount(accessor.type);
    std::vector<T> out = accessor.bufferView >= 0
                             ? readViewElements<T>(accessor, components, component_size, field)
                             : zeroElements<T>(accessor, components, field);
    if (accessor.sparse.isSparse) {
        applySparse(accessor, field, components, component_size, out);
    }
    return out;
}

// Accessor `index`, checked to exist, to have the expected type and a componentType glTF
// allows (unnormalized unsigned integers for indices).
const tinygltf::Accessor& GltfLoader::checkedAccessor(int index, int expected_type, bool indices,
                                                      const std::string& field) const {
    if (index < 0 || static_cast<size_t>(index) >= m_model.accessors.size()) {
        fail(ErrorCode::OutOfRange, field + " is out of range (" +
                                        std::to_string(m_model.accessors.size()) + " accessors)");
    }
    const tinygltf::Accessor& accessor = m_model.accessors[static_cast<size_t>(index)];
    if (accessor.type != expected_type) {
        fail(ErrorCode::InvalidArgument, field + " has type " + typeName(accessor.type) +
                                             ", expected " + typeName(expected_type));
    }
    if (componentSize(accessor.componentType) == 0) {
        fail(ErrorCode::BadEnum, field + " has componentType " +
                                     std::to_string(accessor.componentType) +
                                     ", which glTF 2.0 does not allow here");
    }
    if (indices &&
        (accessor.componentType == TINYGLTF_COMPONENT_TYPE_BYTE ||
         accessor.componentType == TINYGLTF_COMPONENT_TYPE_SHORT ||
         accessor.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT || accessor.normalized)) {
        fail(ErrorCode::BadEnum, field + " must hold unnormalized unsigned integers");
    }
    return accessor;
}

// Refuses `count` elements of `components` T's when they do not fit the budget. Predicted
// before the vector is allocated, so that no count in the file can make the expansion
// exceed the budget (a sparse accessor's zeros are backed by nothing).
template <class T>
void GltfLoader::checkExpansion(size_t count, size_t components, const std::string& field) const {
    const uint64_t per_element = uint64_t(components) * sizeof(T);
    const uint64_t bytes = count > UINT64_MAX / per_element ? UINT64_MAX : count * per_element;
    if (!m_budget.fits(bytes)) {
        fail(ErrorCode::OutOfRange,
             m_budget.refusal(field + " (" + std::to_string(count) + " x " +
                                  std::to_string(components) + " x " + std::to_string(sizeof(T)) +
                                  " bytes, expanded)",
                              bytes));
    }
}

// The elements of an accessor with a bufferView, converted to T.
template <class T>
std::vector<T> GltfLoader::readViewElements(const tinygltf::Accessor& accessor, size_t components,
                                            size_t component_size, const std::string& field) const {
    const size_t element_size = components * component_size;
    const size_t count = accessor.count;
    const std::span<const uint8_t> view = bufferViewBytes(accessor.bufferView, field);
    const size_t view_stride = m_model.bufferViews[size_t(accessor.bufferView)].byteStride;
    const size_t stride = view_stride != 0 ? view_stride : element_size;
    if (stride < element_size) {
        fail(ErrorCode::InconsistentSize,
             field + ": bufferViews[" + std::to_string(accessor.bufferView) + "].byteStride " +
                 std::to_string(view_stride) + " is smaller than one element (" +
                 std::to_string(element_size) + " bytes)");
    }
    checkRange(view.size(), accessor.byteOffset, count, stride, element_size, field);
    checkExpansion<T>(count, components, field);
    std::vector<T> out(count * components);
    for (size_t i = 0; i < count; ++i) {
        const uint8_t* element = view.data() + accessor.byteOffset + i * stride;
        for (size_t c = 0; c < components; ++c) {
            out[i * components + c] = static_cast<T>(readComponent(
                element + c * component_size, accessor.componentType, accessor.normalized));
        }
    }
    return out;
}

// glTF: an accessor without a bufferView is all zeros (until sparse values apply).
template <class T>
std::vector<T> GltfLoader::zeroElements(const tinygltf::Accessor& accessor, size_t components,
                                        const std::string& field) const {
    if (!accessor.sparse.isSparse) {
        fail(ErrorCode::InvalidArgument, field + " has neither a bufferView nor sparse "
                                                 "values");
    }
    // Nothing in the file backs these zeros, so bound them before allocating: a corrupt
    // count must give an error, not exhaust memory.
    const size_t count = accessor.count;
    if (count > kMaxUnbackedElements) {
        fail(ErrorCode::OutOfRange,
             field + ": count " + std::to_string(count) +
                 " is too large for an accessor without a bufferView (at most " +
                 std::to_string(kMaxUnbackedElements) + ")");
    }
    checkExpansion<T>(count, components, field);
    return std::vector<T>(count * components, T(0));
}

void GltfLoader::applySparse(const tinygltf::Accessor& accessor, const std::string& field,
                             size_t components, size_t component_size, auto& out) const {
    using T = typename std::remove_reference_t<decltype(out)>::value_type;
    const auto& sparse = accessor.sparse;
    if (sparse.count < 1 || static_cast<size_t>(sparse.count) > accessor.count) {
        fail(ErrorCode::OutOfRange, field + ": sparse.count " + std::to_string(sparse.count) +
                                        " must be in 1.." + std::to_string(accessor.count));
    }
    if (sparse.indices.byteOffset < 0 || sparse.values.byteOffset < 0) {
        fail(ErrorCode::OutOfRange, field + ": sparse byteOffset must be >= 0");
    }
    const int index_type = sparse.indices.componentType;
    if (index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
        index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
        fail(ErrorCode::BadEnum, field + ": sparse.indices.componentType " +
                                     std::to_string(index_type) + " is not an unsigned type");
    }
    const size_t count = static_cast<size_t>(sparse.count);
    const size_t index_size = componentSize(index_type);
    const size_t element_size = components * component_size;
    // Sparse index and value arrays are tightly packed (glTF forbids byteStride on them).
    const std::span<const uint8_t> index_view =
        bufferViewBytes(sparse.indices.bufferView, field + " sparse.indices");
    checkRange(index_view.size(), size_t(sparse.indices.byteOffset), count, index_size, index_size,
               field + " sparse.indices");
    const std::span<const uint8_t> value_view =
        bufferViewBytes(sparse.values.bufferView, field + " sparse.values");
    checkRange(value_view.size(), size_t(sparse.values.byteOffset), count, element_size,
               element_size, field + " sparse.values");
    for (size_t i = 0; i < count; ++i) {
        const double target =
            readComponent(index_view.data() + size_t(sparse.indices.byteOffset) + i * index_size,
                          index_type, false);
        if (target >= double(accessor.count)) {
            fail(ErrorCode::OutOfRange, field + ": sparse index " +
                                            std::to_string(uint64_t(target)) + " >= count " +
                                            std::to_string(accessor.count));
        }
        const uint8_t* element =
            value_view.data() + size_t(sparse.values.byteOffset) + i * element_size;
        for (size_t c = 0; c < components; ++c) {
            out[size_t(target) * components + c] = static_cast<T>(readComponent(
                element + c * component_size, accessor.componentType, accessor.normalized));
        }
    }
}

std::span<const uint8_t> GltfLoader::bufferViewBytes(int view_index,
                                                     const std::string& field) const {
    if (view_index < 0 || static_cast<size_t>(view_index) >= m_model.bufferViews.size()) {
        fail(ErrorCode::OutOfRange,
             field + ": bufferView " + std::to_string(view_index) + " is out of range (" +
                 std::to_string(m_model.bufferViews.size()) + " bufferViews)");
    }
    const tinygltf::BufferView& view = m_model.bufferViews[static_cast<size_t>(view_index)];
    const std::string view_field = "bufferViews[" + std::to_string(view_index) + "]";
    if (view.buffer < 0 || static_cast<size_t>(view.buffer) >= m_model.buffers.size()) {
        fail(ErrorCode::OutOfRange, field + ": " + view_field + ".buffer " +
                                        std::to_string(view.buffer) + " is out of range");
    }
    const std::vector<unsigned char>& data = m_model.buffers[size_t(view.buffer)].data;
    if (view.byteOffset > data.size() || view.byteLength > data.size() - view.byteOffset) {
        fail(ErrorCode::Truncated,
             field + ": " + view_field + " (byteOffset " + std::to_string(view.byteOffset) +
                 ", byteLength " + std::to_string(view.byteLength) + ") exceeds buffer " +
                 std::to_string(view.buffer) + " (" + std::to_string(data.size()) + " bytes)");
    }
    return {data.data() + view.byteOffset, view.byteLength};
}

// offset + (count - 1) * stride + element_size <= available, without overflow.
void GltfLoader::checkRange(size_t available, size_t offset, size_t count, size_t stride,
                            size_t element_size, const std::string& field) const {
    if (count == 0) {
        return;
    }
    const bool fits = offset <= available && element_size <= available - offset &&
                      (count - 1) <= (available - offset - element_size) / stride;
    if (!fits) {
        fail(ErrorCode::OutOfRange, field + ": " + std::to_string(count) + " elements of " +
                                        std::to_string(element_size) + " bytes (stride " +
                                        std::to_string(stride) + ", byteOffset " +
                                        std::to_string(offset) + ") exceed the " +
                                        std::to_string(available) + "-byte bufferView");
    }
}

// The instantiations gltf_primitives.cpp uses (vertex attributes and indices).
template std::vector<float> GltfLoader::readAccessor<float>(int, int, bool,
                                                            const std::string&) const;
template std::vector<uint32_t> GltfLoader::readAccessor<uint32_t>(int, int, bool,
                                                                  const std::string&) const;

} // namespace probekit::baker::gltf
