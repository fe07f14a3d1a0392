// A cave file that reaches up into the server: layering_test.sh must name it.
#include "server/x.hpp"
