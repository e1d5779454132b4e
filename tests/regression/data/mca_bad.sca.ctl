DSET ^mca_bad.sca
OPTIONS LITTLE_ENDIAN
TITLE kumo bad-input test: 2 phase functions on 4 angles
UNDEF 1.0e+37
XDEF 4 LINEAR 1 1
YDEF 1 LINEAR 1 1
ZDEF 2 LINEAR 1 1
TDEF 1 LINEAR 00:00Z01JAN2000 1YR
VARS 2
ang 1 99 Angles (deg.)
phs 2 99 Phase function
ENDVARS
