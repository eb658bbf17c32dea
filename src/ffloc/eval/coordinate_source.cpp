#include "ffloc/eval/coordinate_source.h"
