#include "ffloc/data/synthetic/synthetic.h"
