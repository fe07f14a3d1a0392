// layering_fixture: a server header.
#pragma once
