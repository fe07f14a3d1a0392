// layering_fixture: a header beside relative.cpp.
#pragma once
