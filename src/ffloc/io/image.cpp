#include "ffloc/io/image.h"
