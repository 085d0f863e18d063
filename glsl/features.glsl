// Feature switches, tested with ordinary `if`s so that one source serves two builds.
// Specialised (the default): the host defines each switch as a literal (true, false; SH_DEGREE a number), the compiler
// folds every `if` on it and the variant carries only the features the scene and the
// settings use. GENERAL (`--general`): every switch is a uniform, one variant serves
// every setting, and the frame pays for all of it; it exists to measure the saving.
#if GENERAL
uniform int u_sh_degree;
uniform bool u_mip;
uniform bool u_mip_modulation;
uniform bool u_gs_compensation;
uniform bool u_alpha_clamp;
#define SH_DEGREE u_sh_degree
#define MIP u_mip
#define MIP_MODULATION u_mip_modulation
#define GS_COMPENSATION u_gs_compensation
#define ALPHA_CLAMP u_alpha_clamp
#define COLOR_AT_LOAD false
#endif
