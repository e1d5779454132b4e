DSET ^mca_bad.atm
OPTIONS LITTLE_ENDIAN
TITLE kumo bad-input test: 2 x 1 voxels, one layer, apf 3 and 1.5
UNDEF 1.0e+37
XDEF 2 LINEAR 1 1
YDEF 1 LINEAR 1 1
ZDEF 1 LINEAR 1 1
TDEF 1 LINEAR 00:00Z01JAN2000 1YR
VARS 5
tmpa3d 1 99 Temperature perturbation (K)
abst3d 1 99 Absorption coefficient perturbation (/m)
extp3d 1 99 Extinction coefficient (/m)
omgp3d 1 99 Single scattering albedo
apfp3d 1 99 Phase function specification parameter
ENDVARS
