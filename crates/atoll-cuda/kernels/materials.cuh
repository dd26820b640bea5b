// Which f16 coefficient of a material (`RayRecord::coeffs`,
// `GpuMaterial::coeffs`) holds which parameter, per material kind: the
// generated block below is `atoll_render::material_layout`, so kernels
// name slots instead of repeating the Rust layout's numbers.
#pragma once

// BEGIN GENERATED materials (src/header.rs; regenerate: ATOLL_BLESS=1 cargo test -p atoll-cuda header)
inline constexpr unsigned int COEFF_DIFFUSE_REFLECTANCE = 0u;
inline constexpr unsigned int COEFF_CONDUCTOR_ETA = 0u;
inline constexpr unsigned int COEFF_CONDUCTOR_K = 3u;
inline constexpr unsigned int COEFF_CONDUCTOR_ALPHA_X = 6u;
inline constexpr unsigned int COEFF_CONDUCTOR_ALPHA_Y = 7u;
inline constexpr unsigned int COEFF_CONDUCTOR_TANGENT = 8u;
inline constexpr unsigned int COEFF_DIELECTRIC_ETA = 0u;
inline constexpr unsigned int COEFF_DIELECTRIC_ALPHA_X = 1u;
inline constexpr unsigned int COEFF_DIELECTRIC_ALPHA_Y = 2u;
inline constexpr unsigned int COEFF_DIELECTRIC_TANGENT = 3u;
inline constexpr unsigned int COEFF_DIFFUSE_TRANSMISSION_REFLECTANCE = 0u;
inline constexpr unsigned int COEFF_DIFFUSE_TRANSMISSION_TRANSMITTANCE = 3u;
inline constexpr unsigned int COEFF_THIN_DIELECTRIC_ETA = 0u;
inline constexpr unsigned int COEFF_MIX_AMOUNT_PROGRAM = 0u;
inline constexpr unsigned int COEFF_COATED_DIFFUSE_REFLECTANCE = 0u;
inline constexpr unsigned int COEFF_COATED_DIFFUSE_ALPHA_X = 3u;
inline constexpr unsigned int COEFF_COATED_DIFFUSE_ALPHA_Y = 4u;
inline constexpr unsigned int COEFF_COATED_DIFFUSE_ETA = 5u;
inline constexpr unsigned int COEFF_COATED_DIFFUSE_THICKNESS = 6u;
inline constexpr unsigned int COEFF_COATED_DIFFUSE_ALBEDO = 7u;
inline constexpr unsigned int COEFF_COATED_DIFFUSE_G = 10u;
inline constexpr unsigned int COEFF_COATED_DIFFUSE_MAX_DEPTH = 11u;
inline constexpr unsigned int COEFF_COATED_DIFFUSE_N_SAMPLES = 12u;
inline constexpr unsigned int COEFF_COATED_DIFFUSE_TANGENT = 13u;
inline constexpr unsigned int COEFF_COATED_CONDUCTOR_ETA = 0u;
inline constexpr unsigned int COEFF_COATED_CONDUCTOR_K = 3u;
inline constexpr unsigned int COEFF_COATED_CONDUCTOR_CONDUCTOR_ALPHA_X = 6u;
inline constexpr unsigned int COEFF_COATED_CONDUCTOR_CONDUCTOR_ALPHA_Y = 7u;
inline constexpr unsigned int COEFF_COATED_CONDUCTOR_INTERFACE_ALPHA_X = 8u;
inline constexpr unsigned int COEFF_COATED_CONDUCTOR_INTERFACE_ALPHA_Y = 9u;
inline constexpr unsigned int COEFF_COATED_CONDUCTOR_INTERFACE_ETA = 10u;
inline constexpr unsigned int COEFF_COATED_CONDUCTOR_THICKNESS = 11u;
inline constexpr unsigned int COEFF_COATED_CONDUCTOR_ALBEDO = 12u;
inline constexpr unsigned int COEFF_COATED_CONDUCTOR_G = 15u;
inline constexpr unsigned int COEFF_PRINCIPLED_BASE_COLOR = 0u;
inline constexpr unsigned int COEFF_PRINCIPLED_METALLIC = 3u;
inline constexpr unsigned int COEFF_PRINCIPLED_ROUGHNESS = 4u;
inline constexpr unsigned int COEFF_PRINCIPLED_SPECULAR = 5u;
inline constexpr unsigned int COEFF_PRINCIPLED_SPECULAR_TINT = 6u;
inline constexpr unsigned int COEFF_PRINCIPLED_SHEEN = 7u;
inline constexpr unsigned int COEFF_PRINCIPLED_SHEEN_TINT = 8u;
inline constexpr unsigned int COEFF_PRINCIPLED_CLEARCOAT = 9u;
inline constexpr unsigned int COEFF_PRINCIPLED_CLEARCOAT_GLOSS = 10u;
inline constexpr unsigned int COEFF_PRINCIPLED_TRANSMISSION = 11u;
inline constexpr unsigned int COEFF_PRINCIPLED_ETA = 12u;
inline constexpr unsigned int COEFF_HAIR_SIGMA_A = 0u;
inline constexpr unsigned int COEFF_HAIR_ETA = 3u;
inline constexpr unsigned int COEFF_HAIR_BETA_M = 4u;
inline constexpr unsigned int COEFF_HAIR_BETA_N = 5u;
inline constexpr unsigned int COEFF_HAIR_ALPHA = 6u;
inline constexpr unsigned int COEFF_HAIR_TANGENT = 7u;
inline constexpr unsigned int COEFF_HAIR_OFFSET = 10u;
inline constexpr unsigned int COEFF_MEASURED_BRDF = 0u;
inline constexpr unsigned int COEFF_MEASURED_TANGENT = 1u;
inline constexpr unsigned int COEFF_SUBSURFACE_ETA = 0u;
inline constexpr unsigned int COEFF_SUBSURFACE_ALPHA_X = 1u;
inline constexpr unsigned int COEFF_SUBSURFACE_ALPHA_Y = 2u;
inline constexpr unsigned int COEFF_SUBSURFACE_TANGENT = 3u;
inline constexpr unsigned int COEFF_SUBSURFACE_EXIT_NORMALISATION = 6u;
inline constexpr unsigned int COATED_CONDUCTOR_MAX_DEPTH = 10u;
inline constexpr unsigned int COATED_CONDUCTOR_N_SAMPLES = 1u;
inline constexpr unsigned int MEASURED_HEADER_WORDS = 30u;
// END GENERATED materials
