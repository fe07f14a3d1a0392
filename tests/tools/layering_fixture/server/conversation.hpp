// A protocol core that includes Asio: layering_test.sh must name it.
#pragma once

#include <boost/asio.hpp>
