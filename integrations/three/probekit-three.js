// probekit volumes in three.js 0.187: `probekit export FILE.pvol --format three -o OUT.json`
// writes OUT.json (header) and OUT.bin (data); this module turns them into a light probe grid
// ready for scene.add (docs/engines.md#threejs; exporters/src/three.cpp describes the bytes).
//
//   import { loadProbekitGrid } from './probekit-three.js';
//   const grid = await loadProbekitGrid('lighting/room.json');
//   scene.add(grid);
//
// WebGLRenderer uses LightProbeGridWebGL (the default); WebGPURenderer uses LightProbeGrid from
// three/addons/lighting/LightProbeGrid.js, which reads the same atlas:
//   loadProbekitGrid(url, { GridClass: LightProbeGrid }).
//
// three.js interpolates probes plainly. A volume baked with visibility (probekit's default)
// carries it in OUT.bin; useProbekitVisibility(material, grid) makes a WebGL material weigh each
// probe by it as probekit's sampler does, so light does not leak through thin walls.
import {
    Data3DTexture,
    FloatType,
    HalfFloatType,
    LinearFilter,
    NearestFilter,
    RGBAFormat,
    ShaderChunk,
    UnsignedByteType,
    Vector3,
} from 'three';
import { LightProbeGridWebGL } from 'three/addons/lighting/LightProbeGridWebGL.js';

const FORMAT = 'probekit-three-lightprobegrid';

function dataTexture(array, width, height, depth, type, filter) {
    const texture = new Data3DTexture(array, width, height, depth);
    texture.format = RGBAFormat;
    texture.type = type;
    texture.minFilter = filter;
    texture.magFilter = filter;
    texture.generateMipmaps = false;
    texture.unpackAlignment = 1;
    texture.needsUpdate = true;
    return texture;
}

// The atlas as a half or float RGBA 3D texture, linear filtering (three.js samples it with the
// hardware filter), the .bin's little-endian values read in place.
function atlasTexture(atlas, bin) {
    const half = atlas.type === 'half';
    const ArrayType = half ? Uint16Array : Float32Array;
    const count = atlas.byteLength / ArrayType.BYTES_PER_ELEMENT;
    const data = new ArrayType(bin, atlas.byteOffset ?? 0, count);
    return dataTexture(data, atlas.width, atlas.height, atlas.depth,
                       half ? HalfFloatType : FloatType, LinearFilter);
}

function visibilityTexture(vis, bin) {
    const data = new Uint8Array(bin, vis.byteOffset, vis.byteLength);
    return dataTexture(data, vis.width, vis.height, vis.depth, UnsignedByteType, NearestFilter);
}

/**
 * A light probe grid from an exported header (OUT.json, parsed) and its data (OUT.bin).
 * Its boundingBox is the header's bounds, its resolution the header's; the probes are at the
 * cell centres. grid.userData.probekit holds the header; grid.userData.probekitVisibility the
 * visibility texture, or null. dispose() frees both textures.
 */
export function createProbekitGrid(header, bin, { GridClass = LightProbeGridWebGL } = {}) {
    if (header.format !== FORMAT || header.version !== 1)
        throw new Error(`probekit-three: not a version 1 ${FORMAT} header`);
    for (const part of [header.atlas, header.visibility]) {
        const end = part ? (part.byteOffset ?? 0) + part.byteLength : 0;
        if (bin.byteLength < end)
            throw new Error(`probekit-three: ${header.atlas.file} holds ${bin.byteLength} ` +
                            `bytes, the header wants ${end}`);
    }
    const min = new Vector3().fromArray(header.bounds.min);
    const max = new Vector3().fromArray(header.bounds.max);
    const size = new Vector3().subVectors(max, min);
    const [nx, ny, nz] = header.resolution;
    const grid = new GridClass(size.x, size.y, size.z, nx, ny, nz);
    grid.position.addVectors(min, max).multiplyScalar(0.5);
    grid.updateBoundingBox();
    // The exact bounds, not centre +- size / 2 rounded again.
    grid.boundingBox.min.copy(min);
    grid.boundingBox.max.copy(max);
    grid.texture = atlasTexture(header.atlas, bin);
    const visibility = header.visibility ? visibilityTexture(header.visibility, bin) : null;
    grid.userData.probekit = header;
    grid.userData.probekitVisibility = visibility;
    const disposeGrid = grid.dispose.bind(grid);
    const atlas = grid.texture;
    grid.dispose = () => {
        atlas.dispose();
        if (visibility) visibility.dispose();
        disposeGrid();
    };
    return grid;
}

/**
 * Fetches OUT.json and the .bin it names (relative to it) and returns createProbekitGrid's grid.
 */
export async function loadProbekitGrid(url, options = {}) {
    const base = typeof location === 'undefined' ? undefined : location.href;
    const jsonUrl = new URL(url, base);
    const response = await fetch(jsonUrl);
    if (!response.ok) throw new Error(`probekit-three: ${jsonUrl}: HTTP ${response.status}`);
    const header = await response.json();
    const binUrl = new URL(header.atlas.file, jsonUrl);
    const binResponse = await fetch(binUrl);
    if (!binResponse.ok) throw new Error(`probekit-three: ${binUrl}: HTTP ${binResponse.status}`);
    return createProbekitGrid(header, await binResponse.arrayBuffer(), options);
}

// Replaces lightprobes_pars_fragment (three.js's grid lookup) for one material. The sample
// point, the bounds test and the irradiance are three.js's; the interpolation is probekit's
// (runtime/include/probekit/runtime/sampler.hpp, step V; formats/include/probekit/formats/
// visibility.hpp): the eight probes around the point are fetched one by one, each trilinear
// weight times (its visibility + floor), normalised. Grids other than the one whose bounds
// pkVisMin / pkVisMax name are interpolated trilinearly the same way, without the weights.
const visibilityChunk = /* glsl */ `
#if NUM_LIGHT_PROBE_GRIDS > 0
uniform highp sampler3D probesSH[ NUM_LIGHT_PROBE_GRIDS ];
uniform vec3 probesMin[ NUM_LIGHT_PROBE_GRIDS ];
uniform vec3 probesMax[ NUM_LIGHT_PROBE_GRIDS ];
uniform vec3 probesResolution[ NUM_LIGHT_PROBE_GRIDS ];
uniform highp sampler3D pkVis;
uniform vec3 pkVisMin;
uniform vec3 pkVisMax;
uniform float pkVisRamp;
uniform float pkVisFloor;

vec3 pkSamplePoint( vec3 p, vec3 n, vec3 lo, vec3 hi, vec3 res ) {
	return p + 0.5 * n * ( hi - lo ) / res;
}

bool isInsideLightProbeGrid( vec3 p, vec3 n, vec3 lo, vec3 hi, vec3 res ) {
	vec3 q = pkSamplePoint( p, n, lo, hi, res );
	vec3 slack = 0.01 * ( hi - lo ) / res;
	return all( lessThanEqual( lo - slack, q ) ) && all( lessThanEqual( q, hi + slack ) );
}

// One half-axis term of visibility.hpp's probeVisibility.
float pkAxisVisibility( float o, float towardsPlus, float towardsMinus ) {
	if ( o == 0.0 ) return 1.0;
	float d = o > 0.0 ? towardsPlus : towardsMinus;
	return clamp( 1.0 - ( abs( o ) - d ) / pkVisRamp, 0.0, 1.0 );
}

float pkProbeVisibility( ivec3 probe, vec3 offset, int nz ) {
	vec4 xy = texelFetch( pkVis, probe, 0 );
	vec4 z = texelFetch( pkVis, ivec3( probe.xy, probe.z + nz ), 0 );
	float v = pkAxisVisibility( offset.x, xy.r, xy.g );
	v = min( v, pkAxisVisibility( offset.y, xy.b, xy.a ) );
	return min( v, pkAxisVisibility( offset.z, z.r, z.g ) );
}

// E(n) = sum A_l L_lm Y_lm(n), formats/CONVENTIONS.md's basis; c[k] holds coefficient k.
vec3 pkIrradiance( vec3 c[ 9 ], vec3 n ) {
	const float a0 = 3.14159265 * 0.282095;
	const float a1 = 2.09439510 * 0.488603;
	const float a2 = 0.78539816;
	vec3 e = a0 * c[ 0 ] + a1 * ( c[ 1 ] * n.y + c[ 2 ] * n.z + c[ 3 ] * n.x );
	e += a2 * 1.092548 * ( c[ 4 ] * n.x * n.y + c[ 5 ] * n.y * n.z + c[ 7 ] * n.x * n.z );
	e += a2 * 0.315392 * ( 3.0 * n.z * n.z - 1.0 ) * c[ 6 ];
	e += a2 * 0.546274 * ( n.x * n.x - n.y * n.y ) * c[ 8 ];
	return max( e, vec3( 0.0 ) );
}

vec3 getLightProbeGridIrradiance( highp sampler3D atlas, vec3 lo, vec3 hi, vec3 res, vec3 p, vec3 n ) {
	bool weighted = all( equal( lo, pkVisMin ) ) && all( equal( hi, pkVisMax ) );
	vec3 g = ( pkSamplePoint( p, n, lo, hi, res ) - lo ) * res / ( hi - lo ) - 0.5;
	g = clamp( g, vec3( 0.0 ), res - 1.0 );
	ivec3 base = ivec3( floor( g ) );
	ivec3 last = ivec3( res ) - 1;
	vec3 f = g - vec3( base );
	int nz = int( res.z );
	vec4 s[ 7 ];
	for ( int t = 0; t < 7; t ++ ) s[ t ] = vec4( 0.0 );
	float total = 0.0;
	for ( int corner = 0; corner < 8; corner ++ ) {
		ivec3 up = ivec3( corner & 1, ( corner >> 1 ) & 1, ( corner >> 2 ) & 1 );
		ivec3 probe = min( base + up, last );
		vec3 axis = mix( 1.0 - f, f, vec3( up ) );
		float w = axis.x * axis.y * axis.z;
		if ( weighted ) w *= pkProbeVisibility( probe, g - vec3( probe ), nz ) + pkVisFloor;
		total += w;
		for ( int t = 0; t < 7; t ++ )
			s[ t ] += w * texelFetch( atlas, ivec3( probe.xy, t * ( nz + 2 ) + 1 + probe.z ), 0 );
	}
	float floats[ 28 ];
	for ( int t = 0; t < 7; t ++ )
		for ( int j = 0; j < 4; j ++ ) floats[ 4 * t + j ] = s[ t ][ j ] / total;
	vec3 c[ 9 ];
	for ( int k = 0; k < 9; k ++ )
		c[ k ] = vec3( floats[ 3 * k ], floats[ 3 * k + 1 ], floats[ 3 * k + 2 ] );
	return pkIrradiance( c, n );
}
#endif
`;

/**
 * Makes a WebGL material (MeshLambertMaterial, MeshStandardMaterial, ...) interpolate the probes
 * of `grid` (from createProbekitGrid / loadProbekitGrid) with probekit's visibility weights.
 * A grid without visibility data leaves the material as it is. Returns the material.
 */
export function useProbekitVisibility(material, grid) {
    const visibility = grid.userData.probekitVisibility;
    if (!visibility) return material;
    const header = grid.userData.probekit.visibility;
    const previous = material.onBeforeCompile;
    material.onBeforeCompile = (shader, renderer) => {
        previous.call(material, shader, renderer);
        shader.uniforms.pkVis = { value: visibility };
        shader.uniforms.pkVisMin = { value: grid.boundingBox.min };
        shader.uniforms.pkVisMax = { value: grid.boundingBox.max };
        shader.uniforms.pkVisRamp = { value: header.ramp };
        shader.uniforms.pkVisFloor = { value: header.floor };
        const lights = ShaderChunk.lights_pars_begin.replace(
            '#include <lightprobes_pars_fragment>', visibilityChunk);
        shader.fragmentShader = shader.fragmentShader.replace('#include <lights_pars_begin>', lights);
    };
    const key = material.customProgramCacheKey.bind(material);
    material.customProgramCacheKey = () => key() + '|probekit-visibility';
    material.needsUpdate = true;
    return material;
}
