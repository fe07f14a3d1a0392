// A cave file that names its neighbour relative to its folder: layering_test.sh must name it.
#include "near.hpp"
