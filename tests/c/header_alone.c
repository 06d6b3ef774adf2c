/* The header compiles on its own, first thing in a translation unit. */
#include "precisemc.h"
#include "precisemc.h" /* include guard */

/* Use a few declarations so the unit is not empty. */
typedef pmc_status (*pmc_extract_fn)(const pmc_volume *, double, const pmc_options *, pmc_mesh **);
pmc_extract_fn pmc_header_alone_extract = pmc_extract;
