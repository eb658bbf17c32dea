#include "ffloc/pose/pnp.h"
